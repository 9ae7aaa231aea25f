# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.run_slam(dynamic='htx') and the detector-input helpers (include/ds3d/dynamic_sources.hpp)."""
import os
import pathlib

import numpy as np
import pytest

import ds3d

FIXTURE = pathlib.Path(__file__).resolve().parents[2] / "tests" / "data" / "htx" / "tiny_weights.safetensors"


def test_run_slam_with_htx_and_composite(tmp_path):
    ds3d.synth.generate(tmp_path, frames=4, seed=3, humans=1)
    for spec in ("htx", "htx+geometric"):
        a = ds3d.run_slam(tmp_path, dynamic=spec, weights=FIXTURE, detect_every=2, min_score=0.0,
                          threaded=False)
        b = ds3d.run_slam(tmp_path, dynamic=spec, weights=str(FIXTURE), detect_every=2,
                          min_score=0.0, threaded=True)
        assert a.shape == (4, 8) and np.all(np.isfinite(a))
        assert np.array_equal(a, b)  # deterministic, threads or not
    c = ds3d.run_slam(tmp_path, dynamic="htx", weights=FIXTURE, min_score=0.0, hold_frames=0)
    assert c.shape == (4, 8) and np.all(np.isfinite(c))
    d = ds3d.run_slam(tmp_path, dynamic="htx", weights=FIXTURE, min_score=0.0, segment_frames=0)
    assert d.shape == (4, 8) and np.all(np.isfinite(d))
    e = ds3d.run_slam(tmp_path, dynamic="htx", weights=FIXTURE, min_score=0.0,
                      segment_outside_boxes=False)
    assert e.shape == (4, 8) and np.all(np.isfinite(e))


def test_run_slam_bad_dynamic_options(tmp_path):
    with pytest.raises(RuntimeError, match="nonexistent"):
        ds3d.run_slam(tmp_path, dynamic="htx", weights="/nonexistent/w.safetensors")
    with pytest.raises(ValueError, match="bogus"):
        ds3d.run_slam(tmp_path, dynamic="htx+bogus", weights=FIXTURE)
    with pytest.raises(ValueError):
        ds3d.run_slam(tmp_path, dynamic="htx", weights=FIXTURE, detect_every=0)
    with pytest.raises(ValueError):
        ds3d.run_slam(tmp_path, dynamic="htx", weights=FIXTURE, min_score=1.5)
    with pytest.raises(ValueError, match="hold_frames"):
        ds3d.run_slam(tmp_path, dynamic="htx", weights=FIXTURE, hold_frames=-1)
    with pytest.raises(ValueError, match="segment_frames"):
        ds3d.run_slam(tmp_path, dynamic="htx", weights=FIXTURE, segment_frames=-1)


def test_detector_input_round_trip():
    rng = np.random.default_rng(0)
    cloud = rng.uniform([-2, -1, 0.5], [2, 1.5, 4], (500, 3)).astype(np.float32)
    R = ds3d.upright_rotation(np.array([0.0, -1.0, 0.0]))
    assert np.allclose(R @ np.array([0, -1, 0], np.float32), [0, 0, 1])
    pts, rows = ds3d.make_detector_input(cloud, R, num_points=256, seed=5)
    assert pts.shape == (256, 3) and rows.shape == (256,) and len(set(rows.tolist())) == 256
    assert np.allclose(pts, cloud[rows] @ R.T, atol=1e-6)
    pts2, rows2 = ds3d.make_detector_input(cloud, R, num_points=256, seed=5)
    assert np.array_equal(rows, rows2)
    with pytest.raises(ValueError):
        ds3d.upright_rotation(np.array([0.0, 1.0, 0.0]))
    with pytest.raises(ValueError):
        ds3d.make_detector_input(cloud, R, num_points=0)


def test_upright_rotation_matches_the_trainers_convention():
    """Inference (C++ upright_rotation) must align clouds exactly as the training data was aligned
    (ds3d.htx.data.gravity_rotation: Z = floor normal, Y = optical axis on the floor)."""
    from ds3d.htx import data

    rng = np.random.default_rng(4)
    for _ in range(50):
        # Cameras pitched and rolled by up to ~40 degrees: the floor normal seen by the camera.
        up = np.array([0.0, -1.0, 0.0]) + rng.uniform(-0.8, 0.8, 3)
        up[1] = -abs(up[1]) - 0.2
        R_cpp = ds3d.upright_rotation(up)
        R_py = data.gravity_rotation(None, up)
        assert np.allclose(R_cpp, R_py, atol=1e-6), (up, R_cpp, R_py)


def test_sparse_detector_refuses_devices_fifos_and_bad_shapes(tmp_path):
    # A device or FIFO would be read without end; the reader refuses it by file type at once.
    with pytest.raises(RuntimeError, match="/dev/urandom: not a regular file"):
        ds3d.SparseDetector.load("/dev/urandom")
    fifo = tmp_path / "weights.fifo"
    os.mkfifo(fifo)
    with pytest.raises(RuntimeError, match="weights.fifo: not a regular file"):
        ds3d.SparseDetector.load(str(fifo))
    det = ds3d.SparseDetector.load(str(FIXTURE))
    bad = np.zeros((10, 4), np.float32)
    with pytest.raises(ValueError, match=r"ds3d.SparseDetector.detect: points .*\(10, 4\)"):
        det.detect(bad)
    with pytest.raises(ValueError, match=r"ds3d.SparseDetector.run: points .*\(10, 4\)"):
        det.run(bad)
    # float64 and non-contiguous float32 inputs are converted, as before.
    pts = np.random.default_rng(0).uniform(-1, 1, (64, 3))
    assert np.array_equal(det.detect(pts), det.detect(np.asfortranarray(pts.astype(np.float32))))
