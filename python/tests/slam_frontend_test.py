# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
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
