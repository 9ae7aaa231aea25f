# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.htx model, sampling rules, export and box helpers."""
import json
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")
from ds3d import htx  # noqa: E402
from ds3d.htx import boxes as B  # noqa: E402
from ds3d.htx import ops  # noqa: E402


def test_profiles_and_parameter_count():
    fast, quality = htx.build_model("fast"), htx.build_model("quality")
    assert fast.config["num_centres"] == 384 and quality.config["num_centres"] == 512
    n = sum(p.numel() for p in fast.parameters())
    assert 0.9e6 < n < 1.0e6  # spec §0: 0.95 M
    with pytest.raises(ValueError, match="profile"):
        htx.build_model("huge")
    with pytest.raises(ValueError, match="unknown key"):
        htx.build_model("fast", bogus=1)


def test_build_model_is_seeded():
    a, b, c = htx.build_model(seed=1), htx.build_model(seed=1), htx.build_model(seed=2)
    sa, sb, sc = a.state_dict(), b.state_dict(), c.state_dict()
    assert all(torch.equal(sa[k], sb[k]) for k in sa)
    assert not all(torch.equal(sa[k], sc[k]) for k in sa)


def brute_fps(p, k, pad=1e-3):
    p = p.astype(np.float32)
    out, dist = [0], np.full(len(p), 1e10, np.float32)
    for _ in range(1, k):
        d = p - p[out[-1]]
        dist = np.minimum(dist, d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
        cand = [j for j in range(len(p)) if float(p[j] @ p[j]) > pad]
        out.append(max(cand, key=lambda j: (dist[j], -j)))
    return out


def test_fps_matches_brute_force_and_skips_padding():
    rng = np.random.default_rng(0)
    p = rng.uniform(-1, 1, (200, 3)).astype(np.float32)
    p[5] = 0.0  # padding: never picked
    got = ops.farthest_point_sample(torch.from_numpy(p), 30).tolist()
    assert got == brute_fps(p, 30)
    assert 5 not in got[1:]
    assert got[0] == 0


def test_ball_query_first_by_index():
    p = np.array([[0, 0, 0], [1, 0, 0], [0.1, 0, 0], [0.05, 0, 0], [0.2, 0, 0], [0.3, 0, 0]], np.float32)
    idx = ops.ball_query(torch.from_numpy(p), torch.from_numpy(p[:1]), 0.25, 4)
    assert idx.tolist() == [[0, 2, 3, 4]]  # index order, not nearest; 1 and 5 are outside
    idx = ops.ball_query(torch.from_numpy(p), torch.from_numpy(p[1:2]), 0.25, 3)
    assert idx.tolist() == [[1, 1, 1]]  # empty slots repeat the first found


def test_forward_shapes_and_finite():
    m = htx.build_model("fast")
    pts = np.random.default_rng(1).uniform([-2, 0.5, 0], [2, 4, 2], (1000, 3)).astype(np.float32)
    out = m(torch.from_numpy(pts), with_parts=True)
    last = out["layers"][-1]
    assert last["center"].shape == (64, 3) and out["part_logits"].shape == (1000, 4)
    assert all(torch.isfinite(v).all() for v in last.values())
    assert torch.all(last["angle"] > -math.pi) and torch.all(last["angle"] <= math.pi)
    # centre offsets within +-0.5 m of the query, sizes within the scene extent
    assert torch.all((last["center"] - out["query_xyz"]).abs() <= 0.5)
    extent = torch.from_numpy(pts.max(0) - pts.min(0))
    assert torch.all(last["size"] <= extent + 1e-5)
    det = htx.reference_detect(m, pts)
    assert det.shape[1] == 9 and np.all(np.isfinite(det))
    assert np.all((det[:, 7] >= 0) & (det[:, 7] <= 1))  # score = p[class] * objectness
    assert np.all(det[:, 8] == 0)  # one class (person) in the default config


def test_export_folds_batchnorm_exactly(tmp_path):
    m = htx.build_model("fast", seed=4)
    path = tmp_path / "w.safetensors"
    htx.export(m, str(path))
    raw = path.read_bytes()
    n = int.from_bytes(raw[:8], "little")
    assert (8 + n) % 8 == 0
    header = json.loads(raw[8:8 + n])
    assert header["__metadata__"]["format"] == "ds3d-htx"
    tensors, meta = htx.read_safetensors(str(path))
    assert json.loads(meta["config"]) == m.config
    assert not any("running" in k or "bn" in k for k in tensors)
    # folded first SA layer reproduces linear + BN + ReLU
    x = torch.randn(50, 3)
    ref = m.pre_encoder[0](x).detach().numpy()
    w, b = tensors["pre_encoder.mlp.0.weight"], tensors["pre_encoder.mlp.0.bias"]
    np.testing.assert_allclose(np.maximum(x.numpy() @ w.T + b, 0), ref, atol=1e-5)


def test_safetensors_round_trip_scalar(tmp_path):
    path = tmp_path / "s.safetensors"
    htx.write_safetensors(str(path), {"s": np.asarray(np.float32(2.5)), "v": np.arange(3, dtype=np.int64)}, {"a": "b"})
    t, meta = htx.read_safetensors(str(path))
    assert t["s"].shape == () and float(t["s"]) == 2.5 and t["v"].tolist() == [0, 1, 2] and meta == {"a": "b"}


def test_box_conventions():
    box = np.array([1.0, 2.0, 0.5, 2.0, 1.0, 1.0, math.pi / 2])
    c = B.corners(box)
    # theta = pi/2: length (2 m) along Y
    assert np.allclose(c[:, 1].max() - c[:, 1].min(), 2.0) and np.allclose(c[:, 0].max() - c[:, 0].min(), 1.0)
    assert np.allclose(B.aabb(box)[0], np.concatenate([c.min(0), c.max(0)]))
    # heading arrow: local +x maps to world (cos t, -sin t)
    assert np.allclose(B.to_local(np.array([[1.0, 1.5, 0.5]]), box), [[0.5, 0, 0]])
    th = np.array([0.0, 0.1, math.pi / 2, math.pi, -2.0, 3.1])
    b, r = B.encode_angle(th)
    assert np.all((r >= -1) & (r < 1))
    dec = B.decode_angle(b, r)
    assert np.allclose(np.mod(dec - th + math.pi, 2 * math.pi) - math.pi, 0, atol=1e-9)


def test_giou_properties():
    a = np.array([[0, 0, 0, 1, 1, 1, 0.0]])
    assert np.allclose(B.generalized_iou_3d(a, a), 1.0)
    rot = a.copy()
    rot[0, 6] = math.pi / 2  # a unit cube rotated by 90 degrees is the same cube
    assert np.allclose(B.generalized_iou_3d(a, rot), 1.0)
    far = np.array([[5, 0, 0, 1, 1, 1, 0.0]])
    g = B.generalized_iou_3d(a, far)[0, 0]
    assert -1 <= g < 0
    # 45-degree square vs axis-aligned: intersection of a unit square and its rotation is
    # the regular octagon of area 2 (sqrt 2 - 1) = 0.8284
    r45 = a.copy()
    r45[0, 6] = math.pi / 4
    area = B.footprint_intersection_area(a, r45)[0]
    assert area == pytest.approx(2 * (math.sqrt(2) - 1), abs=1e-9)


def test_nms_same_class():
    boxes = np.array([[0, 0, 0, 1, 1, 1, 0], [0.05, 0, 0, 1, 1, 1, 0], [0.05, 0, 0, 1, 1, 1, 0], [3, 0, 0, 1, 1, 1, 0]])
    keep = htx.nms_3d_same_class(boxes, [0.9, 0.8, 0.7, 0.6], [0, 0, 1, 0])
    assert keep == [0, 2, 3]
