# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
import json

import numpy as np
import pytest

import ds3d
from textured_images import textured


def test_static_camera_stays_at_origin():
    slam = ds3d.Slam(ds3d.FrontendConfig())
    rgb = textured(1)
    depth = np.full(rgb.shape[:2], 10000, np.uint16)  # a wall 2 m away
    for i in range(5):
        pose = slam.track(rgb, depth, 0.1 * i)
        assert pose.shape == (4, 4)
        assert np.all(np.isfinite(pose))
        assert slam.last_tracked
    slam.finish()
    assert np.allclose(pose, np.eye(4), atol=1e-3)
    traj = slam.trajectory()
    assert traj.shape == (5, 8)
    assert np.allclose(traj[:, 0], 0.1 * np.arange(5))
    pts = slam.map_points()
    assert pts.dtype == np.float32 and pts.shape[1] == 3 and len(pts) > 100
    assert np.allclose(pts[:, 2], 2.0, atol=0.01)


def test_bad_input_raises_value_error():
    slam = ds3d.Slam()
    with pytest.raises(ValueError):
        slam.track(np.zeros((10, 10, 3), np.uint8), None, 0.0)
    with pytest.raises(ValueError):
        slam.track(np.zeros((480, 640), np.uint8), None, 0.0)
    slam.track(np.zeros((480, 640, 3), np.uint8), None, 1.0)
    assert slam.last_state == "not_initialized"
    with pytest.raises(ValueError):
        slam.track(np.zeros((480, 640, 3), np.uint8), None, 0.5)  # time went backwards
    cfg = ds3d.FrontendConfig()
    cfg.fx = -1.0
    with pytest.raises(ValueError):
        ds3d.Slam(cfg)
    with pytest.raises(ValueError):
        ds3d.run_slam(".", max_frames=-1)
    with pytest.raises(RuntimeError):
        ds3d.run_slam("/nonexistent/dataset")


def test_refinement_options_are_exposed_and_validated():
    cfg = ds3d.FrontendConfig()
    assert cfg.refine_frame_poses is True and cfg.refine_rounds == 2
    assert cfg.fuse_neighbors is False and 0.0 < cfg.keyframe_ref_ratio < 1.0
    cfg.refine_rounds = -1
    with pytest.raises(ValueError, match="refine_rounds"):
        cfg.validate()
    cfg = ds3d.FrontendConfig()
    assert cfg.smooth_acceleration == 3.0
    cfg.smooth_acceleration = -1.0
    with pytest.raises(ValueError, match="smooth_acceleration must be >= 0"):
        cfg.validate()
    cfg = ds3d.FrontendConfig()
    assert cfg.merge_segments is True and cfg.interpolate_lost is True
    # Without refinement the finished trajectory equals the online poses.
    cfg = ds3d.FrontendConfig()
    cfg.refine_frame_poses = False
    cfg.refine_rounds = 0
    cfg.final_global_ba = False
    slam = ds3d.Slam(cfg)
    rgb = textured(2)
    depth = np.full(rgb.shape[:2], 10000, np.uint16)
    online = [slam.track(rgb, depth, 0.1 * i) for i in range(4)]
    slam.finish()
    assert slam.merged_segments == 0 and slam.interpolated_frames == 0
    traj = slam.trajectory()
    assert np.allclose(traj[:, 1:4], [p[:3, 3] for p in online], atol=1e-9)


def test_keyframe_culling_option():
    cfg = ds3d.FrontendConfig()
    assert cfg.cull_keyframes is True
    assert cfg.keyframe_redundancy_ratio == pytest.approx(0.9)
    assert cfg.keyframe_redundant_observers == 3
    cfg.keyframe_redundancy_ratio = 1.5
    with pytest.raises(ValueError, match="keyframe_redundancy_ratio"):
        cfg.validate()
    cfg = ds3d.FrontendConfig()
    cfg.keyframe_redundant_observers = 0
    with pytest.raises(ValueError, match="keyframe_redundant_observers"):
        ds3d.Slam(cfg)
    # A hovering camera (the first frames of a synthetic sequence played forward and back) with a
    # keyframe whenever the mapping is idle: culling removes redundant keyframes, and every frame
    # keeps a finite pose.
    scene = ds3d.synth.Scene("static_room", frames=15, seed=2)
    frames = [scene.render(i) for i in range(15)]
    order = list(range(15)) + list(range(14, -1, -1))
    order = order + order
    counts = {}
    for cull in (False, True):
        cfg = ds3d.FrontendConfig()
        cfg.keyframe_ref_ratio = 1.0
        cfg.cull_keyframes = cull
        slam = ds3d.Slam(cfg)
        for k, i in enumerate(order):
            slam.track(frames[i]["rgb"], frames[i]["depth"], k / 30.0)
        slam.finish()
        traj = slam.trajectory()
        assert traj.shape == (len(order), 8) and np.all(np.isfinite(traj))
        assert len(slam.keyframe_trajectory()) == slam.num_keyframes
        counts[cull] = (slam.num_keyframes, slam.num_culled_keyframes)
    assert counts[False][1] == 0
    assert counts[True][1] > 0
    assert counts[True][0] < counts[False][0]


# --- Frame-by-frame dynamic removal (ds3d.Slam with a SlamConfig) against ds3d.run_slam ---

@pytest.fixture(scope="module")
def walking(tmp_path_factory):
    """A 24-frame synthetic walking sequence (TUM layout) with detections.jsonl: per frame one
    2-D person box around the rendered dynamic mask (the file:PATH format)."""
    folder = tmp_path_factory.mktemp("walking")
    ds3d.synth.generate(folder, scenario="walking_xyz", frames=24, seed=1)
    scene = ds3d.synth.Scene("walking_xyz", frames=24, seed=1)
    lines = []
    for i, t in enumerate(ds3d.RgbdDataset(folder).timestamps):
        v, u = np.nonzero(scene.render(i)["dynamic_mask"])
        boxes = [] if len(u) == 0 else [{"bbox": [float(u.min()), float(v.min()), float(u.max()),
                                                  float(v.max())], "score": 0.9,
                                         "class": "person"}]
        lines.append(json.dumps({"timestamp": float(t), "boxes": boxes}))
    (folder / "detections.jsonl").write_text("\n".join(lines) + "\n")
    return folder


def _track_folder(folder, config):
    ds = ds3d.RgbdDataset(folder)
    slam = ds3d.Slam(config, camera=ds.camera)
    results = []
    for f in ds:  # notebook style: one frame at a time
        pose = slam.track(f["rgb"], f["depth"], f["timestamp"])
        r = slam.last_result
        assert np.array_equal(pose, r.pose)
        results.append(r)
    slam.finish()
    return slam.trajectory(), results


@pytest.mark.parametrize("spec", ["geometric", "file"])
def test_frame_by_frame_dynamic_removal_matches_run_slam(walking, spec):
    if spec == "file":
        spec = "file:" + str(walking / "detections.jsonl")
    cfg = ds3d.SlamConfig(dynamic=spec)
    traj, results = _track_folder(walking, cfg)
    ref = ds3d.run_slam(walking, config=cfg, threaded=False)
    assert traj.shape == (24, 8)
    assert np.array_equal(traj, ref)  # bit-identical: the same source -> masker -> tracking
    if spec == "geometric":  # threaded: the same by design
        assert np.array_equal(ref, ds3d.run_slam(walking, config=cfg))
    dynamic = [int(np.count_nonzero(r.keypoint_status == int(ds3d.KeypointStatus.dynamic)))
               for r in results]
    assert dynamic == [r.num_dynamic for r in results]
    assert np.array_equal(dynamic, ref.per_frame["dynamic"])
    assert sum(dynamic) > 100  # the walking person's keypoints are removed
    r = max(results, key=lambda r: r.num_dynamic)
    assert r.keypoints.shape == (r.num_features, 2) and r.keypoints.dtype == np.float32
    assert r.keypoint_status.dtype == np.uint8 and np.array_equal(
        r.dynamic, r.keypoint_status == int(ds3d.KeypointStatus.dynamic))
    assert r.state in ("tracking", "initialized", "relocalized")
    # The removed keypoints lie on the people: mostly inside the rendered dynamic masks, over the
    # sequence. (Single frames can miss: with the floor at the feet kept static, the box filter
    # takes the wall behind in 2 of the 24 frames of `file`, docs/dynamic.md.)
    scene = ds3d.synth.Scene("walking_xyz", frames=24, seed=1)
    on_mask = 0
    for r in results:
        mask = scene.render(r.index)["dynamic_mask"]
        u, v = np.round(r.keypoints[r.dynamic]).astype(int).T
        on_mask += int(np.count_nonzero(
            mask[np.clip(v, 0, mask.shape[0] - 1), np.clip(u, 0, mask.shape[1] - 1)] > 0))
    assert on_mask > 0.6 * sum(dynamic)


def test_slam_with_a_source_object_and_return_result(walking):
    ds = ds3d.RgbdDataset(walking)
    cfg = ds3d.SlamConfig(dynamic="geometric")
    ref = ds3d.run_slam(walking, config=cfg, max_frames=8, threaded=False)
    slam = ds3d.Slam(ds3d.SlamConfig(), camera=ds3d.Camera(ds.camera),
                     dynamic=ds3d.make_dynamic_source("geometric"))
    for i in range(8):
        f = ds[i]
        r = slam.track(f["rgb"], f["depth"], f["timestamp"], return_result=True)
        assert isinstance(r, ds3d.TrackResult) and r.index == i
    slam.finish()
    assert np.array_equal(slam.trajectory(), ref)
    with pytest.raises(TypeError, match="camera is required"):
        ds3d.Slam(ds3d.SlamConfig(dynamic="geometric"))
    with pytest.raises(TypeError, match="masker"):
        ds3d.Slam(ds3d.SlamConfig(), camera="tum1", masker="hdbscan")
    with pytest.raises(ValueError, match="gate"):
        ds3d.Slam(ds3d.SlamConfig(dynamic="none", gate="motion"), camera="tum1")


# --- run_slam's result object, progress and early stop ---

def test_run_slam_result_and_progress(walking, capsys):
    seen = []
    res = ds3d.run_slam(walking, dynamic="geometric", max_frames=10, threaded=False,
                        progress=lambda r, done, total: seen.append((r.index, done, total)))
    assert isinstance(res, ds3d.SlamResult) and isinstance(res, np.ndarray)
    assert res.shape == (10, 8) and type(res.trajectory) is np.ndarray
    assert np.array_equal(np.asarray(res), res.trajectory) and not res.stopped_early
    assert seen == [(i, i + 1, 10) for i in range(10)]
    assert res.keyframes.shape[1] == 8 and 1 <= len(res.keyframes) <= 10
    pf = res.per_frame
    assert set(pf) >= {"index", "timestamp", "state", "tracked", "keyframe", "features",
                       "dynamic", "inliers"}
    assert np.array_equal(pf["index"], np.arange(10)) and np.array_equal(pf["timestamp"],
                                                                         res[:, 0])
    assert pf["state"][0] == "initialized" and pf["tracked"].dtype == bool
    assert pf["keyframe"].sum() >= len(res.keyframes)  # culled keyframes keep their flag
    capsys.readouterr()
    ds3d.run_slam(walking, max_frames=3, progress=True)
    assert "3/3" in capsys.readouterr().err  # tqdm or the plain status line, on stderr
    with pytest.raises(TypeError, match="progress"):
        ds3d.run_slam(walking, max_frames=3, progress="yes")


def test_run_slam_stops_on_keyboard_interrupt(walking):
    def interrupt_at_6(result, done, total):
        if done == 6:
            raise KeyboardInterrupt

    res = ds3d.run_slam(walking, dynamic="geometric", threaded=False, progress=interrupt_at_6)
    assert res.stopped_early and res.total == 24 and res.shape == (6, 8)
    # The frames read so far are tracked and finished as a 6-frame run would be.
    assert np.array_equal(res, ds3d.run_slam(walking, dynamic="geometric", max_frames=6))
    # Threaded: the frames already read are tracked too; still a prefix, finished.
    res = ds3d.run_slam(walking, dynamic="geometric", threaded=True, progress=interrupt_at_6)
    assert res.stopped_early and 6 <= len(res) < 24

    def fail(result, done, total):
        raise RuntimeError("callback failed")

    with pytest.raises(RuntimeError, match="callback failed"):
        ds3d.run_slam(walking, max_frames=4, progress=fail)


def test_frame_by_frame_matches_the_cli(walking, tmp_path):
    import os
    import pathlib
    import subprocess
    build = pathlib.Path(os.environ.get("DS3D_BUILD_DIR",
                                        pathlib.Path(__file__).resolve().parents[2] / "build"))
    cli = build / "bin" / "ds3d-slam"
    if not cli.exists():
        pytest.skip("ds3d-slam is not built")
    out = tmp_path / "traj.txt"
    subprocess.run([str(cli), str(walking), "--dynamic", "geometric", "--out", str(out),
                    "--quiet"], check=True)
    traj, _ = _track_folder(walking, ds3d.SlamConfig(dynamic="geometric"))
    ref = np.loadtxt(out)  # written with round-trip precision
    assert np.array_equal(ref[:, :4], traj[:, :4])  # stamps and positions: bit-identical
    # Quaternions come from the same matrices, converted in another binary (1 ulp at most).
    assert np.allclose(ref[:, 4:], traj[:, 4:], rtol=0, atol=4e-16)
