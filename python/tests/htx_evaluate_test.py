# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""HTx evaluation helpers (python/ds3d/htx/evaluate.py): rotated 3-D IoU, VOC AP, model loading."""
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("ds3d")

from ds3d.htx import build_model, evaluate, export, reference_detect  # noqa: E402


def test_iou_3d():
    b = np.array([0, 0, 0, 2, 1, 1, 0.3])
    np.testing.assert_allclose(evaluate.iou_3d(b, b[None]), [1.0], atol=1e-9)
    shifted = b.copy()
    shifted[0] += 1.0 * math.cos(0.3)  # half a length along the heading arrow (x, -y)
    shifted[1] -= 1.0 * math.sin(0.3)
    np.testing.assert_allclose(evaluate.iou_3d(b, shifted[None]), [1 / 3], atol=1e-9)
    sq = np.array([0, 0, 0, 1, 1, 2, 0.0])
    rot = sq.copy()
    rot[6] = math.pi / 2
    np.testing.assert_allclose(evaluate.iou_3d(sq, rot[None]), [1.0], atol=1e-9)
    up = sq.copy()
    up[2] = 1.0  # half the height overlaps
    np.testing.assert_allclose(evaluate.iou_3d(sq, up[None]), [1 / 3], atol=1e-9)
    assert evaluate.iou_3d(sq, np.zeros((0, 7))).shape == (0,)


def _row(box, score):
    return np.r_[box, score, 0.0].astype(np.float32)


def test_average_precision():
    g1 = np.array([[0, 2, 0, 0.5, 0.5, 1.7, 0]])
    g2 = np.array([[1, 3, 0, 0.5, 0.5, 1.7, 0]])
    fp = np.array([5, 5, 0, 0.5, 0.5, 1.7, 0])
    dets = [np.stack([_row(g1[0], 0.8), _row(fp, 0.3)]), np.stack([_row(g2[0], 0.7)])]
    ap, rec, n = evaluate.average_precision(dets, [g1, g2], 0.5)
    assert (ap, rec, n) == (pytest.approx(1.0), pytest.approx(1.0), 2)
    dets = [np.stack([_row(g1[0], 0.8), _row(fp, 0.9)]), np.stack([_row(g2[0], 0.7)])]
    ap, _, _ = evaluate.average_precision(dets, [g1, g2], 0.5)
    assert ap == pytest.approx(2 / 3)
    # a duplicate of a matched box is a false positive; a missed box caps the recall
    dets = [np.stack([_row(g1[0], 0.8), _row(g1[0], 0.6)]), np.zeros((0, 9), np.float32)]
    ap, rec, _ = evaluate.average_precision(dets, [g1, g2], 0.25)
    assert rec == pytest.approx(0.5) and ap == pytest.approx(0.5)
    np.testing.assert_array_equal(evaluate.matched(dets[0], np.r_[g1, g2], 0.25), [True, False])


def test_safetensors_model_round_trip(tmp_path):
    model = build_model("fast", seed=4)
    path = tmp_path / "m.safetensors"
    export(model, path)
    back = evaluate._model_from_safetensors(path)
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(-2, 2, 1500), rng.uniform(1, 4, 1500), rng.uniform(-1, 1, 1500)].astype(np.float32)
    a = reference_detect(model, pts, return_details=True)[1]
    b = reference_detect(back, pts, return_details=True)[1]
    for k in ("center", "size", "objectness", "part_logits"):
        np.testing.assert_allclose(a[k], b[k], atol=1e-4)


def test_shipped_weights_find_synthetic_people():
    import pathlib

    import ds3d
    from ds3d.htx import data

    path = pathlib.Path(__file__).resolve().parents[2] / "models" / "htx_lite_fast.safetensors"
    if not path.exists() or not hasattr(ds3d, "SparseDetector") or not hasattr(ds3d, "synth"):
        pytest.skip("no shipped weights or ds3d built without the detector/generator")
    det = ds3d.SparseDetector.load(str(path))
    assert 0 < det.config.score_threshold < 1
    cam = ds3d.camera_preset("tum_ros")
    scene = ds3d.synth.Scene("walking_static", frames=300, seed=12_000_123, humans=2)  # a test-range seed
    hits = total = 0
    for i in (0, 100, 200):
        s = data.make_frame(scene.render(i), cam, np.random.default_rng(0))
        out = np.asarray(det.detect(s["points"]))
        assert np.isfinite(out).all() and out.shape[1] == 9
        hits += int(evaluate.matched(out, s["boxes"].astype(np.float64), 0.25).sum())
        total += len(s["boxes"])
    assert total > 0 and hits >= 1
