# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Trajectory I/O, ATE/RPE against a fixture's expected numbers, the local ATE per window, bad
arguments raise ValueError."""
import json
import pathlib

import numpy as np
import pytest

import ds3d

FIX = pathlib.Path(__file__).resolve().parents[2] / "tests" / "data" / "trajectory" / "walking_xyz_basic"


def test_ate_and_rpe_match_the_tum_scripts():
    exp = json.loads((FIX / "expected.json").read_text())
    gt = ds3d.read_tum_trajectory(str(FIX / "groundtruth.txt"), keep_zero_quaternion=True)
    est = ds3d.read_tum_trajectory(str(FIX / "estimate.txt"), keep_zero_quaternion=True)
    assert gt.shape == (exp["ate"]["n_gt_poses_read"], 8)
    r = ds3d.evaluate_ate(gt, est)
    assert r.compared_pose_pairs == exp["ate"]["compared_pose_pairs"]
    assert r.rmse == pytest.approx(exp["ate"]["rmse"], rel=1e-9)
    np.testing.assert_allclose(r.rotation, exp["ate"]["alignment"]["rotation"], atol=1e-9)
    assert r.matches.shape == (r.compared_pose_pairs, 9)
    assert np.sqrt(np.mean(r.matches[:, 8] ** 2)) == pytest.approx(r.rmse, rel=1e-12)
    p = ds3d.evaluate_rpe(ds3d.read_tum_trajectory(str(FIX / "groundtruth.txt")),
                          ds3d.read_tum_trajectory(str(FIX / "estimate.txt")), delta=1, delta_unit="f")
    want = exp["rpe"]["delta_1f"]
    assert p.compared_pose_pairs == want["compared_pose_pairs"]
    assert p.translational.rmse == pytest.approx(want["translational"]["rmse"], rel=1e-9)
    assert p.rotational.median == pytest.approx(want["rotational"]["median"], rel=1e-9)
    assert p.pairs.shape == (p.compared_pose_pairs, 6)


def test_write_read_round_trip(tmp_path):
    t = np.zeros((5, 8))
    t[:, 0] = 100 + np.arange(5) * 0.1
    t[:, 1] = np.arange(5)
    t[:, 7] = 1.0
    ds3d.write_tum_trajectory(str(tmp_path / "t.txt"), t)
    np.testing.assert_array_equal(ds3d.read_tum_trajectory(str(tmp_path / "t.txt")), t)


def test_bad_arguments_raise():
    t = np.tile([0, 0, 0, 0, 0, 0, 0, 1.0], (10, 1))
    t[:, 0] = np.arange(10) * 0.01
    with pytest.raises(ValueError, match="align"):
        ds3d.evaluate_ate(t, t, align="se2")
    with pytest.raises(ValueError, match="max_difference"):
        ds3d.evaluate_ate(t, t, max_difference=-1)
    with pytest.raises(ValueError, match="delta unit"):
        ds3d.evaluate_rpe(t, t, delta_unit="km")
    with pytest.raises(RuntimeError):
        ds3d.read_tum_trajectory("/nonexistent/gt.txt")


def test_local_ate_per_window():
    # 10 s at 64 Hz along a curve; 20 poses 0.1 m off in [4 s, 5 s)
    n = 640
    gt = np.zeros((n, 8))
    gt[:, 0] = 100 + np.arange(n) / 64
    a = 0.01 * np.arange(n)
    gt[:, 1], gt[:, 2], gt[:, 3] = np.cos(a), np.sin(a), 0.002 * np.arange(n)
    gt[:, 7] = 1.0
    est = gt.copy()
    est[256:276, 1] += 0.1
    r = ds3d.evaluate_ate(gt, est, window=1.0)
    assert len(r.windows) == 10 and r.num_short_windows == 0
    rmse = [w.rmse for w in r.windows]
    assert max(rmse) == r.worst_window_rmse == r.windows[4].rmse
    assert r.worst_window_rmse > 2 * r.rmse
    assert all(x < 1e-9 for k, x in enumerate(rmse) if k != 4)
    w = r.windows[4]
    assert (w.start, w.end, w.pairs) == (104.0, 104.0 + 63 / 64, 64)
    with pytest.raises(AttributeError):
        w.rmse = 0.0  # read-only
    # one window longer than the sequence is the global ATE
    one = ds3d.evaluate_ate(gt, est, window=100.0)
    assert len(one.windows) == 1
    assert one.windows[0].rmse == pytest.approx(one.rmse, rel=1e-9)
    off = ds3d.evaluate_ate(gt, est)
    assert off.windows == [] and off.worst_window_rmse == 0.0
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="window"):
            ds3d.evaluate_ate(gt, est, window=bad)
