# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.Camera (include/ds3d/camera.hpp): its constructors and every camera argument taking it."""
import pickle

import numpy as np
import pytest

import ds3d


def test_constructors_presets_and_dict_view(tmp_path):
    c = ds3d.Camera(517.3, 516.5, 318.6, 255.3, depth_scale=5000.0)
    assert (c.fx, c.fy, c.cx, c.cy, c.width, c.height) == (517.3, 516.5, 318.6, 255.3, 640, 480)
    assert c["fx"] == 517.3 and dict(c) == c.to_dict() and set(c.keys()) >= {"k1", "depth_scale"}
    for name in ("tum1", "tum2", "tum3", "tum_ros", "bonn"):
        p = ds3d.Camera.preset(name)
        assert p == ds3d.Camera(name) and p.to_dict() == ds3d.camera_preset(name)
        assert ds3d.Camera(ds3d.camera_preset(name)) == p and ds3d.Camera(p) == p
    assert pickle.loads(pickle.dumps(c)) == c and c != ds3d.Camera("tum1")
    (tmp_path / "camera.txt").write_text("fx 520\nfy 521\ncx 320\ncy 240\n")
    assert ds3d.Camera(tmp_path / "camera.txt").fx == 520
    assert "fx=517.3" in repr(c)
    with pytest.raises(ValueError, match="fx"):
        ds3d.Camera(-1.0, 1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="lacks 'cy'"):
        ds3d.Camera({"fx": 1, "fy": 1, "cx": 0})
    with pytest.raises(ValueError, match="unknown key 'f'"):
        ds3d.Camera({"f": 1, "fx": 1, "fy": 1, "cx": 0, "cy": 0})
    with pytest.raises(ValueError, match="preset"):
        ds3d.Camera.preset("kinect")
    with pytest.raises(KeyError):
        c["focal"]


def test_every_camera_argument_takes_a_camera(tmp_path):
    ds3d.synth.generate(tmp_path, frames=3, seed=2)
    cam = ds3d.Camera(ds3d.RgbdDataset(tmp_path).camera)
    ds = ds3d.RgbdDataset(tmp_path, camera=cam)
    assert ds3d.Camera(ds.camera) == cam
    f = ds[0]
    feats = [ds3d.OrbExtractor().extract(f["rgb"], f["depth"], c)
             for c in (cam, cam.to_dict())]
    assert np.array_equal(feats[0].keypoints, feats[1].keypoints)
    objs = ds3d.make_dynamic_source("geometric").detect(f["rgb"], f["depth"], cam, f["timestamp"])
    assert isinstance(objs, ds3d.DynamicObjects)
    assert isinstance(ds3d.image_boxes(objs, cam), list)
    assert ds3d.keypoint_array(feats[0], f["depth"], cam).shape[1] == 3
    cfg = ds3d.FrontendConfig()
    cfg.camera = cam
    assert cfg.camera == cam and cfg.fx == cam.fx
    cfg.set_camera("bonn")
    assert cfg.camera == ds3d.Camera("bonn")
    assert ds3d.Slam(cfg).camera == ds3d.Camera("bonn")
    a = ds3d.run_slam(tmp_path, camera=cam, threaded=False)
    b = ds3d.run_slam(tmp_path, camera=cam.to_dict(), threaded=False)
    assert np.array_equal(a, b) and np.array_equal(a, ds3d.run_slam(tmp_path, threaded=False))
    with pytest.raises(ValueError, match="camera must be a dict"):
        ds3d.run_slam(tmp_path, camera=3.5)


def test_depth_functions_take_a_camera():
    rng = np.random.default_rng(4)
    depth = (rng.uniform(1, 3, (480, 640)) * 5000).astype(np.uint16)
    cam = ds3d.Camera(525.0, 525.0, 319.5, 239.5)
    ref = ds3d.depth_to_points(depth, 525.0, 525.0, 319.5, 239.5, stride=4)
    for c in (cam, cam.to_dict()):
        r = ds3d.depth_to_points(depth, c, stride=4)
        assert np.array_equal(r.points, ref.points)
    metres = depth.astype(np.float64) / 5000.0  # float images: converted, no depth_scale
    assert np.allclose(ds3d.depth_to_points(metres, cam, stride=4).points, ref.points)
    ref = ds3d.preprocess(depth, 525.0, 525.0, 319.5, 239.5, stride=4)
    r = ds3d.preprocess(depth, camera=cam, stride=4)
    assert np.array_equal(r.points, ref.points)
    with pytest.raises(ValueError, match="but the camera is 240x320"):
        ds3d.depth_to_points(depth, ds3d.Camera(525.0, 525.0, 160.0, 120.0, 320, 240))
    with pytest.raises(ValueError, match="but the camera is"):
        ds3d.preprocess(depth, ds3d.Camera(525.0, 525.0, 160.0, 120.0, 320, 240))
