# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.OrbExtractor / OrbParams / OrbFeatures (include/ds3d/orb_features.hpp)."""
import numpy as np
import pytest

import ds3d
from textured_images import textured


CAM = ds3d.camera_preset("tum_ros")


def test_features_counts_ranges_and_depth():
    rgb = textured(1)
    depth = np.full(rgb.shape[:2], 10000, np.uint16)  # 2 m at depth_scale 5000
    depth[:, 320:] = 30000  # 6 m: beyond the close threshold (3 m), within max_range (10 m)
    depth[:100] = 0  # missing
    params = ds3d.OrbParams()
    ex = ds3d.OrbExtractor(params)
    f = ex.extract(rgb, depth, CAM)
    n = len(f)
    assert 0.8 * params.num_features <= n <= 1.05 * params.num_features
    kp, und = f.keypoints, f.undistorted
    assert kp.shape == (n, 2) and kp.dtype == np.float32 and np.all(np.isfinite(kp))
    assert np.all((kp[:, 0] >= 0) & (kp[:, 0] <= 639) & (kp[:, 1] >= 0) & (kp[:, 1] <= 479))
    assert np.allclose(und, kp, atol=1e-3)  # tum_ros has no distortion
    assert f.octave.dtype == np.int32 and f.octave.min() == 0 and f.octave.max() == params.num_levels - 1
    assert np.all((f.angle >= 0) & (f.angle < 360)) and np.all(f.size > 0)
    d = f.descriptors
    assert d.shape == (n, 32) and d.dtype == np.uint8 and len(np.unique(d, axis=0)) > 0.9 * n
    z = f.depth
    row = np.round(kp[:, 1]).astype(int)
    col = np.round(kp[:, 0]).astype(int)
    expected = depth[row, col] / 5000.0
    assert np.allclose(z, expected, atol=1e-4)
    assert np.array_equal(f.is_close, (z > 0) & (z <= 3.0)) and f.close_depth == pytest.approx(3.0)
    # Deterministic: the same frame gives the same keypoints and descriptors.
    g = ex.extract(rgb, depth, CAM)
    assert np.array_equal(g.keypoints, kp) and np.array_equal(g.descriptors, d)
    nodepth = ex.extract(rgb, None, CAM)
    assert len(nodepth) == n and not nodepth.depth.any()
    assert ex.level_scale(2) == pytest.approx(1.44)


def test_fewer_features_and_flat_image():
    rgb = textured(2)
    small = ds3d.OrbParams()
    small.num_features = 200
    assert len(ds3d.OrbExtractor(small).extract(rgb, None, CAM)) <= 210
    flat = np.full((480, 640, 3), 128, np.uint8)
    assert len(ds3d.OrbExtractor().extract(flat, None, CAM)) == 0
    assert ds3d.OrbExtractor().extract(flat, None, CAM).descriptors.shape == (0, 32)


def test_bad_input_errors_name_the_parameter():
    ex = ds3d.OrbExtractor()
    rgb = textured(3)
    with pytest.raises(ValueError, match="OrbExtractor.extract: rgb .*float32"):
        ex.extract(rgb.astype(np.float32), None, CAM)
    with pytest.raises(ValueError, match="rgb .*shape \\(480, 640, 4\\)"):
        ex.extract(np.zeros((480, 640, 4), np.uint8), None, CAM)
    with pytest.raises(ValueError, match="depth .*float64"):
        ex.extract(rgb, np.ones((480, 640)), CAM)
    with pytest.raises(ValueError, match="depth is 240x320"):
        ex.extract(rgb, np.zeros((240, 320), np.uint16), CAM)
    with pytest.raises(ValueError, match="rgb is 480x640"):
        ex.extract(rgb, None, dict(CAM, width=320))
    with pytest.raises(ValueError, match="unknown key 'f'"):
        ex.extract(rgb, None, dict(CAM, f=1.0))
    for field, value in (("num_levels", 0), ("scale_factor", 1.0), ("fast_threshold", 300),
                         ("cell_size", 4), ("num_features", 0)):
        p = ds3d.OrbParams()
        setattr(p, field, value)
        with pytest.raises(ValueError, match=field):
            p.validate()
        with pytest.raises(ValueError, match=field):
            ds3d.OrbExtractor(p)
    assert "num_features=1000" in repr(ds3d.OrbParams())
