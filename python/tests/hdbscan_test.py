# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.hdbscan: a fixture round trip against the reference hdbscan 0.8.43, and bad input."""
import json
import pathlib

import numpy as np
import pytest

import ds3d

DATA = pathlib.Path(__file__).resolve().parents[2] / "tests" / "data" / "hdbscan"
CASE = DATA / "keypoints_person_dscale100_s113__mcs15_ms10_eom_multi_eps0p5u"


def _canonical(labels, unstable):
    order = {}
    for i, l in enumerate(labels):
        if l >= 0 and i not in unstable:
            order.setdefault(l, i)
    for i, l in enumerate(labels):
        if l >= 0:
            order.setdefault(l, len(labels) + i)
    rank = {l: r for r, l in enumerate(sorted(order, key=order.get))}
    return np.array([rank[l] if l >= 0 else -1 for l in labels])


def test_matches_reference_fixture():
    params = json.loads((CASE / "params.json").read_text())
    x = np.loadtxt(CASE / "points.csv", delimiter=",")
    r = ds3d.hdbscan(x, min_cluster_size=params["min_cluster_size"],
                     min_samples=params["min_samples"],
                     cluster_selection_method=params["cluster_selection_method"],
                     allow_single_cluster=params["allow_single_cluster"],
                     cluster_selection_epsilon=params["cluster_selection_epsilon"])
    unstable = set(np.atleast_1d(np.loadtxt(CASE / "unstable_points.txt", dtype=int)).tolist()) \
        if (CASE / "unstable_points.txt").stat().st_size else set()
    stable = np.array([i not in unstable for i in range(len(x))])
    ref = np.loadtxt(CASE / "labels_canonical.txt", dtype=int)
    assert r.labels.dtype == np.int32
    np.testing.assert_array_equal(_canonical(r.labels, unstable)[stable], ref[stable])
    np.testing.assert_allclose(r.probabilities[stable],
                               np.loadtxt(CASE / "probabilities.txt")[stable], atol=1e-9)
    np.testing.assert_allclose(r.outlier_scores[stable],
                               np.loadtxt(CASE / "outlier_scores.txt")[stable], atol=1e-9)
    np.testing.assert_allclose(r.core_distances, np.loadtxt(CASE / "core_distances.txt"),
                               rtol=1e-12)
    assert r.condensed_tree.dtype.names == ("parent", "child", "lambda_val", "child_size")
    assert r.single_linkage_tree.shape == (len(x) - 1, 4)
    assert len(r.cluster_persistence) >= r.num_clusters == params["n_clusters"]


def test_scale_and_algorithms_agree():
    rng = np.random.default_rng(0)
    x = np.vstack([rng.normal(c, 0.3, size=(200, 3)) for c in (0.0, 3.0, 6.0)])
    a = ds3d.hdbscan(x, min_cluster_size=15, algorithm="prims")
    b = ds3d.hdbscan(x, min_cluster_size=15, algorithm="boruvka", num_threads=2)
    np.testing.assert_array_equal(np.sort(a.min_spanning_tree[:, 2]),
                                  np.sort(b.min_spanning_tree[:, 2]))
    assert a.num_clusters == 3
    c = ds3d.hdbscan(x * [1.0, 1.0, 0.5], min_cluster_size=15, scale=[1.0, 1.0, 2.0])
    assert c.num_clusters == 3


def test_precomputed():
    rng = np.random.default_rng(1)
    x = np.vstack([rng.normal(c, 0.2, size=(40, 2)) for c in (0.0, 5.0)])
    d = np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(-1))
    r = ds3d.hdbscan_precomputed(d, min_cluster_size=10)
    assert r.num_clusters == 2


@pytest.mark.parametrize("kwargs, match", [
    ({"min_cluster_size": 1}, "min_cluster_size"),
    ({"min_samples": 0}, "min_samples"),
    ({"cluster_selection_method": "nope"}, "cluster_selection_method"),
    ({"algorithm": "dense"}, "algorithm"),
    ({"cluster_selection_epsilon": -1.0}, "cluster_selection_epsilon"),
    ({"min_cluster_size": 2**40}, r"ds3d.hdbscan: min_cluster_size .*1099511627776"),
    ({"min_samples": 2**40}, r"min_samples .*1099511627776"),
    ({"max_cluster_size": -2**40}, "max_cluster_size"),
    ({"num_threads": 2**63}, "num_threads"),
    ({"min_cluster_size": "five"}, "min_cluster_size must be an integer"),
])
def test_bad_params_raise_value_error(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ds3d.hdbscan(np.zeros((10, 2)), **kwargs)


def test_non_finite_row_is_named():
    x = np.zeros((20, 3))
    x[7, 2] = np.nan
    with pytest.raises(ValueError, match="row 7"):
        ds3d.hdbscan(x)


@pytest.mark.parametrize("factor", [1e200, 1e154, 1e-300])
def test_extreme_coordinate_scales_cluster_like_unit_scale(factor):
    # Squared distances of these coordinates overflow or underflow in float64.
    rng = np.random.default_rng(4)
    x = np.vstack([rng.normal(c, 0.2, size=(100, 3)) for c in (0.0, 4.0, 8.0)])
    base = ds3d.hdbscan(x, min_cluster_size=10)
    for algorithm in ("prims", "boruvka", "auto"):
        r = ds3d.hdbscan(x * factor, min_cluster_size=10, algorithm=algorithm)
        # The same partition; ids may be permuted (scaling by 1e200 is not exact, so the
        # merge order of the single-linkage tree, which numbers the clusters, can change).
        assert r.num_clusters == base.num_clusters == 3
        pairs = set(zip(r.labels.tolist(), base.labels.tolist()))
        assert len(pairs) == len({a for a, _ in pairs}) == len({b for _, b in pairs})
        assert np.all(np.isfinite(r.core_distances)) and np.all(r.core_distances > 0)


def test_unrepresentable_extent_raises_value_error():
    x = np.zeros((20, 3))
    x[3, 0], x[4, 0] = 1.5e308, -1.5e308
    with pytest.raises(ValueError, match="row 3 column 0.*supported range"):
        ds3d.hdbscan(x)
