# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.GeometricMotionSource (include/ds3d/geometric_motion.hpp) on short ds3d.synth sequences."""
import numpy as np
import pytest

import ds3d

CAM = ds3d.camera_preset("tum_ros")  # the generator's intrinsics


def box_mask(boxes, shape):
    m = np.zeros(shape, bool)
    for b in boxes:
        m[int(max(b.y_min, 0)):int(b.y_max) + 1, int(max(b.x_min, 0)):int(b.x_max) + 1] = True
    return m


def run(scenario, frames, **params):
    p = ds3d.GeometricMotionParams()
    for k, v in params.items():
        setattr(p, k, v)
    src = ds3d.GeometricMotionSource(p)
    scene = ds3d.synth.Scene(scenario, frames=frames, seed=1)
    for i in range(frames):
        f = scene.render(i)
        yield f, src.detect(f["rgb"], f["depth"], CAM, f["timestamp"], index=i), src


def test_walkers_are_found_where_the_generator_put_them():
    found, dyn_hits, dyn_total, ratios, masks = 0, 0, 0, [], 0
    for f, o, src in run("walking_xyz", 12):
        s = src.last_stats
        assert o.boxes_3d.shape[1:] == (8, 3) and np.all(np.isfinite(o.boxes_3d))
        assert s.num_objects == len(o.boxes_3d) and np.all(np.isfinite(s.T_world_cam))
        t = src.last_tested
        assert t.dtype.names == ("u", "v", "z", "chi2", "moving", "cluster", "candidate")
        assert np.array_equal(t["moving"], t["chi2"] > src.params.moving_chi2)
        assert np.all(t["cluster"][~t["moving"]] == -1) and np.all(t["z"] > 0)
        dm = f["dynamic_mask"] > 0
        px = src.last_moving_pixels
        tested = {(int(a), int(b)) for a, b in src.last_warp_tested}
        assert src.last_warp_tested.shape[1:] == (2,) and len(tested) >= len(px)
        assert all((int(a), int(b)) in tested for a, b in px)  # flagged pixels were tested
        if len(px):
            r = np.clip(np.round(px[:, 1]).astype(int), 0, 479)
            c = np.clip(np.round(px[:, 0]).astype(int), 0, 639)
            near = np.zeros_like(dm)  # the walker, grown by a warp grid step
            ys, xs = np.nonzero(dm)
            for dy in (-4, 0, 4):
                for dx in (-4, 0, 4):
                    near[np.clip(ys + dy, 0, 479), np.clip(xs + dx, 0, 639)] = True
            dyn_hits += near[r, c].sum()
            dyn_total += len(px)
        if f["index"] < 3:
            continue  # a reference and a confirmation are needed first
        cov = box_mask(ds3d.image_boxes(o, CAM), dm.shape)
        assert (cov & dm).any(), f"frame {f['index']}: no box on a walker"
        ratios.append((cov & dm).sum() / cov.sum() / dm.mean())
        found += 1
        # segment_objects (default): the grown segments lie on the walkers and cover most of them.
        pm = o.pixel_mask
        assert pm is not None and pm.shape == dm.shape and pm.dtype == np.uint8
        pm = pm > 0
        assert (pm & dm).sum() > 0.9 * pm.sum(), f"frame {f['index']}: mask off the walkers"
        assert (pm & dm).sum() > 0.5 * dm.sum(), f"frame {f['index']}: mask misses the walkers"
        assert src.last_stats.num_segments >= 1 and src.last_stats.num_segment_cells > 0
        masks += 1
    assert found == 9 and masks == 9
    # The boxes sit on the walkers: typically at least twice as much of their area is dynamic as
    # of the whole image (a frame may report an over-wide box: no per-frame bound).
    assert np.median(ratios) > 2
    assert dyn_hits > 0.8 * dyn_total  # warp evidence lies on (or next to) the walkers


def test_static_scene_reports_nothing_and_is_deterministic():
    for f, o, src in run("static_room", 8):
        assert o.empty, f"frame {f['index']}: {src.last_stats}"
        if f["index"] >= 2:
            assert src.last_stats.pose_ok
    boxes_only = [o for _, o, _ in run("walking_xyz", 5, segment_objects=False)]
    assert all(o.pixel_mask is None for o in boxes_only) and len(boxes_only[-1].boxes_3d) > 0
    a = [o.boxes_3d for _, o, _ in run("walking_xyz", 5)]
    b = [o.boxes_3d for _, o, _ in run("walking_xyz", 5)]
    assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_ego_motion_is_the_cameras_motion_since_the_reference():
    frames = {}
    reported = 0
    for f, o, src in run("static_room", 8):
        frames[f["timestamp"]] = f
        if o.ego_motion is None:
            continue
        reported += 1
        t_ref, T = o.ego_motion
        assert T.shape == (4, 4) and T.dtype == np.float64 and t_ref < f["timestamp"]
        truth = np.linalg.inv(f["T_world_cam"]) @ frames[t_ref]["T_world_cam"]
        assert np.linalg.norm(T[:3, 3] - truth[:3, 3]) < 0.01
    assert reported >= 5
    assert all(o.ego_motion is None for _, o, _ in run("static_room", 4, max_acceleration=0.0))


def test_params_stats_and_errors():
    p = ds3d.GeometricMotionParams()
    assert "num_features=800" in repr(p) and "segment_objects=true" in repr(p)
    assert p.segment_objects is True and p.max_object_width == pytest.approx(1.2)
    src = ds3d.GeometricMotionSource(p)
    assert src.name == "geometric" and src.params.num_features == 800
    assert src.last_tested.shape == (0,) and src.last_moving_pixels.shape == (0, 2)
    assert src.last_warp_tested.shape == (0, 2)
    assert src.last_stats.as_dict()["num_objects"] == 0
    rgb = np.zeros((480, 640, 3), np.uint8)
    assert src.detect(rgb, None, CAM, 0.0).empty  # no depth: nothing
    with pytest.raises(ValueError, match="GeometricMotionSource.*|detect \\(geometric\\): depth"):
        src.detect(rgb, np.zeros((480, 640), np.int32), CAM, 0.1)
    with pytest.raises(ValueError, match="rgb is 480x640"):
        src.detect(rgb, None, dict(CAM, height=240), 0.1)
    for field, value in (("num_features", 0), ("reference_gap", 0), ("match_ratio", 1.5),
                         ("min_pose_inliers", 3), ("image_scale", 0.0), ("min_support", 0.0),
                         ("moving_chi2", float("nan")), ("max_speed", -1.0),
                         ("min_band_support", -0.1), ("max_object_width", 0.0),
                         ("max_acceleration", -1.0)):
        q = ds3d.GeometricMotionParams()
        setattr(q, field, value)
        with pytest.raises(ValueError, match=field):
            q.validate()
        with pytest.raises(ValueError, match=field):
            ds3d.GeometricMotionSource(q)
    assert isinstance(ds3d.make_dynamic_source("geometric"), ds3d.DynamicObjectSource)
