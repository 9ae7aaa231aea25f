# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Part-A2 targets (Python vs C++ to 1e-6), 3DETR losses and matching, SUN RGB-D loader."""
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")
import ds3d  # noqa: E402
from ds3d import htx  # noqa: E402


def random_boxes(rng, m):
    return np.concatenate([rng.uniform([-2, -2, 0], [2, 2, 1], (m, 3)), rng.uniform(0.3, 2.0, (m, 3)),
                           rng.uniform(-math.pi, math.pi, (m, 1))], axis=1).astype(np.float32)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_part_targets_python_matches_cpp(seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-3, -3, -1], [3, 3, 2], (5000, 3)).astype(np.float32)
    boxes = random_boxes(rng, 6)
    py = htx.part_targets(pts, boxes)
    cpp = ds3d.part_a2_targets(pts, boxes)
    np.testing.assert_array_equal(py["label"], cpp["label"])
    np.testing.assert_array_equal(py["box_index"], cpp["box_index"])
    np.testing.assert_allclose(py["part"], cpp["part"], atol=1e-6, rtol=0)
    assert (py["label"] == 1).sum() > 100 and (py["label"] == -1).sum() > 10


def test_part_targets_plus_half_and_bad_input():
    box = np.array([[0, 0, 0, 2, 1, 1, 0.0]], np.float32)
    t = htx.part_targets(np.array([[0, 0, 0], [0.5, 0, 0]], np.float32), box)
    np.testing.assert_allclose(t["part"], [[0.5, 0.5, 0.5], [0.75, 0.5, 0.5]])
    with pytest.raises(ValueError):
        htx.part_targets(np.zeros((1, 3)), np.array([[0, 0, 0, 0, 1, 1, 0]]))
    with pytest.raises(ValueError):
        ds3d.part_a2_targets(np.zeros((1, 3), np.float32), np.array([[0, 0, 0, -1, 1, 1, 0]], np.float32))


def test_hungarian_matching_recovers_planted_queries():
    m = htx.build_model("fast", seed=0)
    pts = np.random.default_rng(3).uniform([-2, 0.5, 0], [2, 4, 2], (2000, 3)).astype(np.float32)
    out = m(torch.from_numpy(pts), all_layers=True)
    last = out["layers"][-1]
    # GT boxes equal to the predictions of queries 5 and 17: matching must find them.
    gt = torch.cat([last["center"], last["size"], last["angle"][:, None]], 1)[[5, 17]].detach().numpy()
    tgt = htx.box_targets(gt, [0, 0], out["scene_min"].numpy(), out["scene_max"].numpy())
    w = dict(htx.losses.SUNRGBD_WEIGHTS, match_obj=0.0, match_cls=0.0)
    qi, gi = htx.hungarian_match(last, tgt, w)
    assert sorted(zip(gi.tolist(), qi.tolist())) == [(0, 5), (1, 17)]


def test_scene_loss_is_finite_and_trains():
    m = htx.build_model("fast", seed=0, num_classes=2, class_names=["person", "chair"])
    m.train()
    rng = np.random.default_rng(0)
    pts = rng.uniform([-2, 0.5, 0], [2, 4, 2], (1500, 3)).astype(np.float32)
    gt = np.array([[0.0, 2.0, 0.85, 0.6, 0.5, 1.7, 0.3], [1.0, 3.0, 0.4, 0.6, 0.6, 0.8, 0.0]])
    opt = torch.optim.AdamW(m.parameters(), lr=1e-3)
    losses = []
    for _ in range(4):
        torch.manual_seed(0)  # same dropout masks each step
        loss, parts = htx.scene_loss(m, pts, gt, [0, 1])
        assert torch.isfinite(loss) and all(np.isfinite(v) for v in parts.values())
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss))
    assert losses[-1] < losses[0]
    loss, _ = htx.scene_loss(m, pts, np.zeros((0, 7)), [])  # empty scene: only background
    assert torch.isfinite(loss)


def test_part_loss_counts_foreground_only():
    logits = torch.zeros(4, 4)
    label = np.array([1, 0, -1, 0])
    target = np.array([[0.5, 0.5, 0.5], [0, 0, 0], [0, 0, 0], [0, 0, 0]], np.float32)
    _, parts = htx.part_loss(logits, label, target)
    assert parts["part_loc"] == pytest.approx(math.log(2), rel=1e-6)  # BCE(0.5, 0.5) per coordinate


def write_scene(folder, sid, pc, bbox, compressed=True):
    (np.savez_compressed if compressed else np.savez)(folder / f"{sid}_pc.npz", pc=pc)
    np.save(folder / f"{sid}_bbox.npy", bbox)


def test_sunrgbd_loader(tmp_path):
    rng = np.random.default_rng(0)
    pc = np.concatenate([rng.uniform(-1, 1, (500, 3)), rng.uniform(0, 1, (500, 3))], 1)
    bbox = np.array([[0.1, 1.0, 0.4, 0.3, 0.6, 0.4, 0.0, 3],          # theta = 0
                     [0.5, 2.0, 0.4, 0.3, 0.6, 0.4, math.pi / 2, 1],  # length along -Y
                     [-0.5, 2.0, 0.4, 0.3, 0.6, 0.4, math.pi - 0.3, 0]])  # mirrored heading
    write_scene(tmp_path, "000001", pc, bbox)
    write_scene(tmp_path, "000002", pc[:10], np.zeros((0, 8)), compressed=False)  # empty scene
    s = htx.load_sunrgbd_scene(str(tmp_path), 1)
    np.testing.assert_allclose(s["boxes"][:, 3:6], 2 * bbox[:, 3:6])
    assert s["classes"].tolist() == [3, 1, 0] and s["points"].dtype == np.float32
    ds = htx.SunRgbdDataset(str(tmp_path), num_points=64, seed=1)
    assert ds.scans == ["000001", "000002"]
    assert ds[1]["sampled"].shape == (64, 3) and ds[1]["boxes"].shape == (0, 7)
    np.testing.assert_array_equal(ds[0]["sampled"], htx.SunRgbdDataset(str(tmp_path), 64, 1)[0]["sampled"])
    with pytest.raises(RuntimeError, match="000003"):
        htx.load_sunrgbd_scene(str(tmp_path), 3)
