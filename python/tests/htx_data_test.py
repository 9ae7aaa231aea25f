# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""HTx training data (python/ds3d/htx/data.py) on a tiny generated dataset."""
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")
ds3d = pytest.importorskip("ds3d")
if not hasattr(ds3d, "synth") or not hasattr(ds3d, "preprocess"):
    pytest.skip("ds3d built without the synthetic generator", allow_module_level=True)

from ds3d.htx import data, ops  # noqa: E402
from ds3d.htx.boxes import points_in_box  # noqa: E402
from ds3d.htx.config import make_config  # noqa: E402
from ds3d.htx.targets import part_targets  # noqa: E402


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("htx_tiny")
    summary = data.generate(out, "train", frames=6, seed=3, frames_per_scene=3, shard_size=4)
    return out, summary


def test_gravity_rotation_level_camera():
    # floor 1.4 m below a level camera: n = (0, -1, 0), d = 1.4 (camera y points down)
    R = data.gravity_rotation([0.0, -1.0, 0.0, 1.4])
    np.testing.assert_allclose(R, [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-12)
    # the same plane with the opposite sign gives the same frame
    np.testing.assert_allclose(data.gravity_rotation([0.0, 1.0, 0.0, -1.4]), R, atol=1e-12)
    np.testing.assert_allclose(data.gravity_rotation(None, (0, -2.0, 0)), R, atol=1e-12)


def test_gravity_rotation_tilted_camera_is_a_rotation_with_up_as_z():
    a = math.radians(20)
    up = np.array([0.0, -math.cos(a), -math.sin(a)])  # camera pitched down by 20 degrees
    R = data.gravity_rotation(np.r_[up, 1.3])
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ up, [0, 0, 1], atol=1e-12)
    fwd = R @ np.array([0.0, 0.0, 1.0])  # the optical axis keeps X = 0 and points forward
    assert abs(fwd[0]) < 1e-12 and fwd[1] > 0


def test_gravity_rotation_rejects_degenerate_input():
    with pytest.raises(ValueError, match="gravity_rotation"):
        data.gravity_rotation([0.0, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="parallel"):
        data.gravity_rotation([0.0, 0.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="gravity_rotation"):
        data.gravity_rotation(None, (np.nan, 1.0, 0.0))


def test_world_boxes_map_points_consistently():
    rng = np.random.default_rng(0)
    # camera 1.4 m high looking along world +x, pitched down by 12 degrees (like the generator)
    base = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], float).T
    p = math.radians(-12)
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    T = np.eye(4)
    T[:3, :3] = base @ rx
    T[:3, 3] = [0.5, 2.5, 1.4]
    box = {"center": [2.5, 2.0, 0.85], "size": [0.6, 0.45, 1.7], "yaw": 0.7}
    R = data.gravity_rotation(None, T[:3, :3].T @ [0, 0, 1.0])
    ub = data.world_boxes_to_upright([box], T, R)[0]
    # points drawn in the world box (local frame, counter-clockwise yaw) land in the upright box
    loc = rng.uniform(-0.49, 0.49, (200, 3)) * np.array(box["size"])
    c, s = math.cos(box["yaw"]), math.sin(box["yaw"])
    pw = loc @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) + box["center"]
    pc = (pw - T[:3, 3]) @ T[:3, :3]  # world -> camera
    assert points_in_box(pc @ R.T, ub).all()
    np.testing.assert_allclose(ub[3:6], box["size"])


def test_scene_seeds_are_disjoint_between_splits():
    tr = set(data.scene_seeds("train", 1000, 10_000_000))
    te = set(data.scene_seeds("test", 1000, 10_000_000))
    va = set(data.scene_seeds("val", 1000, 10_000_000))
    assert not (tr & te) and not (tr & va) and not (va & te)
    with pytest.raises(ValueError, match="split"):
        data.scene_seeds("dev", 3, 0)


def test_tiny_dataset_is_consistent(tiny):
    out, summary = tiny
    ds = data.HtxDataset(out)
    assert len(ds) == summary["frames"] == 6
    cfg = make_config("fast")
    n_boxes = 0
    for i in range(len(ds)):
        s = ds[i]
        p = s["points"]
        assert p.dtype == np.float32 and p.ndim == 2 and p.shape[1] == 3 and 16 <= len(p) <= data.MAX_POINTS
        assert np.isfinite(p).all() and np.isfinite(s["boxes"]).all() and np.isfinite(s["nn_w"]).all()
        assert set(np.unique(s["label"])) <= {-1, 0, 1}
        fg = s["label"] == 1
        assert (s["part"][fg] >= 0).all() and (s["part"][fg] <= 1).all()
        assert (s["human"][fg] > 0).all()  # foreground points see a human pixel
        # every foreground point lies in a labelled box; every labelled box holds enough points
        inside = np.zeros(len(p), bool)
        for b in s["boxes"]:
            k = points_in_box(p, b)
            assert k.sum() >= data.MIN_BOX_POINTS
            inside |= k
        assert inside[fg].all()
        # the stored part targets are Part-A2's (ds3d.htx.targets) for the foreground points
        ref = part_targets(p, s["boxes"])
        np.testing.assert_allclose(s["part"][fg], ref["part"][fg], atol=1e-3)
        R = s["R_up_cam"]
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-5)
        # stored network selections equal the model's own ops
        x = torch.from_numpy(p)
        cidx = ops.farthest_point_sample(x, min(cfg["num_centres"], len(p)))
        np.testing.assert_array_equal(s["centre_idx"], cidx.numpy())
        np.testing.assert_array_equal(s["group"], ops.ball_query(x, x[cidx], cfg["sa_radius"], cfg["sa_samples"]).numpy())
        np.testing.assert_array_equal(s["query_idx"], ops.farthest_point_sample(x[cidx], min(cfg["num_queries"], len(cidx))).numpy())
        nn, w = ops.three_nn_weights(x, x[cidx])
        np.testing.assert_array_equal(s["nn_idx"], nn.numpy())
        np.testing.assert_allclose(s["nn_w"], w.numpy(), rtol=1e-6)
        n_boxes += len(s["boxes"])
    assert n_boxes == summary["boxes"]


def test_generation_is_deterministic(tiny, tmp_path):
    out, _ = tiny
    data.generate(tmp_path, "train", frames=6, seed=3, frames_per_scene=3, shard_size=4)
    a, b = data.HtxDataset(out), data.HtxDataset(tmp_path)
    for i in range(len(a)):
        np.testing.assert_array_equal(a[i]["points"], b[i]["points"])
        np.testing.assert_array_equal(a[i]["boxes"], b[i]["boxes"])
        np.testing.assert_array_equal(a[i]["label"], b[i]["label"])


def test_crowd_share_draws_crowd_scenes_with_their_carried_objects(tmp_path):
    summary = data.generate(tmp_path, "train", frames=4, seed=5, frames_per_scene=2, shard_size=8,
                            crowd_share=1.0)
    ds = data.HtxDataset(tmp_path)
    assert summary["crowd_share"] == 1.0 and len(ds) == 4
    infos = [ds[i]["info"] for i in range(len(ds))]
    assert all(i["scenario"] in data.CROWD_SCENARIOS and 3 <= i["humans"] <= 6 for i in infos)
    assert summary["boxes"] > 0
    # Carried boards, boxes and bags are human pixels inside their carrier's box, so nearly every
    # human point is a foreground label (the rest: people with too few points to be a label).
    human = np.concatenate([ds[i]["human"] > 0 for i in range(len(ds))])
    fg = np.concatenate([ds[i]["label"] == 1 for i in range(len(ds))])
    assert human.sum() > 100 and (human & fg).sum() > 0.9 * human.sum()


def test_crowd_share_zero_keeps_the_scene_stream(tiny, tmp_path):
    out, _ = tiny
    data.generate(tmp_path, "train", frames=6, seed=3, frames_per_scene=3, shard_size=4, crowd_share=0.0)
    a, b = data.HtxDataset(out), data.HtxDataset(tmp_path)
    assert "crowd_share" not in b.info
    for i in range(len(a)):
        np.testing.assert_array_equal(a[i]["points"], b[i]["points"])


def test_bad_arguments_raise(tmp_path):
    with pytest.raises(ValueError, match="crowd_share"):
        data.generate(tmp_path, "train", frames=1, seed=1, crowd_share=1.5)
    with pytest.raises(ValueError, match="frames"):
        data.generate(tmp_path, "train", frames=0, seed=1)
    with pytest.raises(ValueError, match="split"):
        data.generate(tmp_path, "dev", frames=1, seed=1)
    with pytest.raises(ValueError, match="no .npz"):
        data.HtxDataset(tmp_path)
