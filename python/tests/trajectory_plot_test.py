# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.plot_ate (include/ds3d/slam/trajectory_plot.hpp), the image of ds3d-eval ate --plot."""
import numpy as np
import pytest

import ds3d


def _circle(n=60, noise=0.0, seed=0):
    t = np.linspace(0, 2 * np.pi, n)
    rng = np.random.default_rng(seed)
    rows = np.zeros((n, 8))
    rows[:, 0] = 10 + t
    rows[:, 1], rows[:, 2] = np.cos(t), np.sin(t)
    rows[:, 1:4] += rng.normal(0, noise, (n, 3))
    rows[:, 7] = 1.0
    return rows


def test_plot_ate_image_and_file(tmp_path):
    gt, est = _circle(), _circle(noise=0.02, seed=1)
    img = ds3d.plot_ate(gt, est, title="circle", width=800, height=400)
    assert img.shape == (400, 800, 3) and img.dtype == np.uint8 and img.std() > 0
    out = tmp_path / "ate.png"
    same = ds3d.plot_ate(gt, est, out, title="circle", width=800, height=400)
    assert np.array_equal(img, same) and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    ds3d.write_tum_trajectory(str(tmp_path / "gt.txt"), gt)
    ds3d.write_tum_trajectory(str(tmp_path / "est.txt"), est)
    from_files = ds3d.plot_ate(tmp_path / "gt.txt", str(tmp_path / "est.txt"), window=2.0)
    assert from_files.shape == (640, 1400, 3)
    assert not np.array_equal(ds3d.plot_ate(gt, gt), ds3d.plot_ate(gt, est))


def test_plot_ate_bad_input():
    gt = _circle()
    with pytest.raises(ValueError, match="width"):
        ds3d.plot_ate(gt, gt, width=10)
    with pytest.raises(ValueError, match="est must be an"):
        ds3d.plot_ate(gt, gt[:, :7])
    far = gt.copy()
    far[:, 0] += 1000  # no stamp matches
    with pytest.raises(ValueError):
        ds3d.plot_ate(gt, far)
    with pytest.raises(RuntimeError):
        ds3d.plot_ate(gt, gt, "/nonexistent/dir/ate.png")
    assert {"plot_ate", "evaluate_ate", "evaluate_rpe"} <= set(ds3d.__all__)
