# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Round trips of the preprocessing bindings against the golden fixtures (tests/data/preprocess)."""
import json
import pathlib

import numpy as np
import pytest

import ds3d

DATA = pathlib.Path(__file__).resolve().parents[2] / "tests" / "data" / "preprocess"


def _points(case):
    return np.fromfile(DATA / case / "input.bin", dtype="<f4").reshape(-1, 3)


def test_voxel_grid_scratch_release_keeps_results():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1, 1, size=(20000, 3)).astype(np.float32)
    first = ds3d.voxel_grid(pts, 0.01)  # fills this thread's cached scratch
    assert ds3d.release_voxel_grid_scratch() > 0
    assert ds3d.release_voxel_grid_scratch() == 0
    again = ds3d.voxel_grid(pts, 0.01)
    np.testing.assert_array_equal(again.keys, first.keys)
    np.testing.assert_array_equal(again.centroids, first.centroids)
    np.testing.assert_array_equal(again.representative, first.representative)


def test_voxel_grid_matches_golden_float32_and_float64():
    pts = _points("cube_1k")
    gold = np.loadtxt(DATA / "cube_1k" / "voxel_0.2x0.3x0.5.csv", delimiter=",", skiprows=1)
    for arr in (pts, pts.astype(np.float64)):
        r = ds3d.voxel_grid(arr, (0.2, 0.3, 0.5))
        assert r.keys.dtype == np.int64 and r.keys.shape == (len(gold), 3)
        np.testing.assert_array_equal(r.keys, gold[:, :3].astype(np.int64))
        np.testing.assert_array_equal(r.counts, gold[:, 3].astype(np.uint32))
        np.testing.assert_allclose(r.centroids, gold[:, 4:], atol=1e-5, rtol=1e-6)
        assert r.representative.shape == (len(gold),)
    cubic = ds3d.voxel_grid(pts, 0.1, num_threads=2)
    assert len(cubic.counts) == json.loads((DATA / "cube_1k" / "case.json").read_text())[
        "outputs"]["voxel"][0]["n_voxels"]


def test_remove_radius_outliers_matches_golden():
    pts = _points("nan_inf_2k")
    gold = np.loadtxt(DATA / "nan_inf_2k" / "radius_R0.1_k5_kept.txt", dtype=np.int64)
    r = ds3d.remove_radius_outliers(pts, 0.1, 5)
    np.testing.assert_array_equal(r.kept, gold)
    r64 = ds3d.remove_radius_outliers(pts.astype(np.float64), radius=0.1, min_neighbors=5,
                                      num_threads=2)
    np.testing.assert_array_equal(r64.kept, gold)
    kd = ds3d.remove_radius_outliers(pts, 0.1, 5, search="kdtree")
    np.testing.assert_array_equal(kd.kept, gold)


def test_ransac_plane_finds_the_golden_plane():
    pts = _points("plane_box_10k")
    meta = json.loads((DATA / "plane_box_10k" / "case.json").read_text())["outputs"]["plane"]
    r = ds3d.ransac_plane(pts, 0.01, max_iterations=1000, confidence=1.0, seed=3)
    assert r.found and r.iterations == 1000
    a, b, c, d = r.plane
    dist = np.abs(pts.astype(np.float64) @ np.array([a, b, c]) + d)
    assert (dist < 0.01).sum() >= 0.97 * meta["inlier_count"]
    np.testing.assert_array_equal(r.inliers, np.flatnonzero(dist < 0.01))
    assert abs(abs(np.dot([a, b, c], meta["plane"][:3])) - 1) < 1e-3
    assert not ds3d.ransac_plane(np.zeros((2, 3), np.float32), 0.01).found
    # Keyword conveniences: an integer tuple prior, a plain list of points.
    prior = ds3d.ransac_plane(pts, 0.01, normal_prior=(0, 0, 1), max_angle_deg=30)
    assert prior.found and prior.plane[2] > 0.9
    assert ds3d.ransac_plane(pts[:50].tolist(), 1).found


def test_depth_to_points_distortion_per_call():
    # The undistortion table is cached per camera: calls alternating between two distortions
    # must each get their own rays.
    d = np.full((48, 64), 10000, np.uint16)
    kw = dict(fx=50.0, fy=50.0, cx=31.5, cy=23.5)
    plain = ds3d.depth_to_points(d, **kw).points
    a = ds3d.depth_to_points(d, distortion=(-0.2, 0.0, 0.001, 0.0, 0.0), **kw).points
    b = ds3d.depth_to_points(d, distortion=(0.1, 0.0, 0.0, 0.0, 0.0), **kw).points
    a2 = ds3d.depth_to_points(d, distortion=(-0.2, 0.0, 0.001, 0.0, 0.0), **kw).points
    np.testing.assert_array_equal(a, a2)
    assert abs(a[0, 0] - plain[0, 0]) > 1e-3 and abs(b[0, 0] - plain[0, 0]) > 1e-3
    assert abs(a[0, 0] - b[0, 0]) > 1e-3
    off = ds3d.depth_to_points(d, distortion=(-0.2, 0.0, 0.001, 0.0, 0.0), undistort=False, **kw)
    np.testing.assert_array_equal(off.points, plain)


def test_depth_to_points_matches_golden_rows():
    d = DATA / "depth_640x480"
    intr = json.loads((d / "intrinsics.json").read_text())
    depth = np.fromfile(d / "depth_u16.bin", dtype="<u2").reshape(480, 640)
    r = ds3d.depth_to_points(depth, intr["fx"], intr["fy"], intr["cx"], intr["cy"])
    assert r.points.shape == (301183, 3) and r.pixels.shape == (301183, 2)
    sel = r.pixels[:, 1] % 16 == 0
    want = np.fromfile(d / "expected_points_v16.bin", dtype="<f4").reshape(-1, 3)
    want_pix = np.fromfile(d / "expected_pixels_v16_u16.bin", dtype="<u2").reshape(-1, 2)
    np.testing.assert_array_equal(r.pixels[sel], want_pix)
    assert np.all(np.abs(r.points[sel] - want) <= 1e-6 * want[:, 2:3] + 1e-7)
    metres = ds3d.depth_to_points(depth.astype(np.float32) / 5000.0, 525.0, 525.0, 319.5, 239.5,
                                  stride=2, roi=(0, 0, 320, 0))
    assert metres.pixels[:, 0].max() < 320 and np.all(metres.pixels % 2 == 0)


def test_preprocess_runs_on_a_frame():
    depth = np.fromfile(DATA / "depth_640x480" / "depth_u16.bin", dtype="<u2").reshape(480, 640)
    r = ds3d.preprocess(depth, 525.0, 525.0, 319.5, 239.5)
    assert r.points.shape[0] == len(r.source) == r.pixels.shape[0] > 0
    assert np.isfinite(r.points).all()
    assert r.num_voxels == r.points.shape[0] + r.num_ground + r.num_outliers


def test_bad_parameters_raise_value_error():
    pts = np.zeros((10, 3), np.float32)
    with pytest.raises(ValueError, match="leaf_size"):
        ds3d.voxel_grid(pts, -0.1)
    with pytest.raises(ValueError, match="leaf_size"):
        ds3d.voxel_grid(pts, (0.1, 0.1))
    with pytest.raises(ValueError, match="radius"):
        ds3d.remove_radius_outliers(pts, 0.0, 3)
    with pytest.raises(ValueError, match="min_neighbors"):
        ds3d.remove_radius_outliers(pts, 0.1, -1)
    with pytest.raises(ValueError, match="search"):
        ds3d.remove_radius_outliers(pts, 0.1, 3, search="octree")
    with pytest.raises(ValueError, match="distance_threshold"):
        ds3d.ransac_plane(pts, -1.0)
    with pytest.raises(ValueError, match="confidence"):
        ds3d.ransac_plane(pts, 0.01, confidence=2.0)
    with pytest.raises(ValueError, match="num_threads"):
        ds3d.voxel_grid(pts, 0.1, num_threads=-1)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        ds3d.voxel_grid(np.zeros((10, 4), np.float32), 0.1)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        ds3d.remove_radius_outliers("not points", 0.1, 3)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        ds3d.ransac_plane(np.zeros(9), 0.1)
    with pytest.raises(ValueError, match="fx"):
        ds3d.depth_to_points(np.ones((4, 4), np.uint16), -1.0, 1.0, 0.0, 0.0)
