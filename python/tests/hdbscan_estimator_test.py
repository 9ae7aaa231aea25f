# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.HDBSCAN and prediction: every golden case of the reference hdbscan 0.8.43 in
tests/data/hdbscan_predict, the scikit-learn estimator protocol, and bad input."""
import json
import pathlib

import numpy as np
import pytest

import ds3d

DATA = pathlib.Path(__file__).resolve().parents[2] / "tests" / "data" / "hdbscan_predict"
CASES = sorted(p.name for p in DATA.iterdir() if p.is_dir())


def _fit(case):
    params = json.loads((DATA / case / "params.json").read_text())
    x = np.loadtxt(DATA / case / "train.csv", delimiter=",")
    c = ds3d.HDBSCAN(min_cluster_size=params["min_cluster_size"],
                     min_samples=params["min_samples"],
                     cluster_selection_method=params["cluster_selection_method"],
                     algorithm="prims_kdtree", approx_min_span_tree=False,
                     prediction_data=True).fit(x)
    return c, x


def test_six_cases_present():
    assert len(CASES) == 6


@pytest.mark.parametrize("case", CASES)
def test_matches_reference(case):
    c, _ = _fit(case)
    d = DATA / case
    ref_fit = np.loadtxt(d / "fit_labels.txt", dtype=int)
    mapping = {}
    for ours, ref in zip(c.labels_, ref_fit):
        if ours >= 0:
            mapping.setdefault(int(ours), int(ref))
    to_ref = np.array([mapping[i] for i in range(len(mapping))])
    np.testing.assert_array_equal(np.where(c.labels_ >= 0, to_ref[c.labels_], -1), ref_fit)
    query = np.loadtxt(d / "query.csv", delimiter=",")
    labels, probs = ds3d.approximate_predict(c, query)
    assert labels.dtype == np.int32 and probs.dtype == np.float64
    np.testing.assert_array_equal(np.where(labels >= 0, to_ref[labels], -1),
                                  np.loadtxt(d / "predict_labels.txt", dtype=int))
    np.testing.assert_allclose(probs, np.loadtxt(d / "predict_probabilities.txt"), rtol=0, atol=1e-9)
    mv = ds3d.membership_vector(c, query)
    ref_mv = np.loadtxt(d / "membership_vectors.csv", delimiter=",", ndmin=2)
    np.testing.assert_allclose(mv, ref_mv[:, to_ref], rtol=0, atol=1e-9)
    if (d / "all_points_membership_vectors.csv").exists():
        ref_all = np.loadtxt(d / "all_points_membership_vectors.csv", delimiter=",", ndmin=2)
        np.testing.assert_allclose(ds3d.all_points_membership_vectors(c), ref_all[:, to_ref],
                                   rtol=0, atol=1e-9)


def test_attributes_and_trees():
    c, x = _fit(CASES[0])
    n = len(x)
    assert c.labels_.shape == c.probabilities_.shape == c.outlier_scores_.shape == (n,)
    k = int(c.labels_.max()) + 1
    assert c.cluster_persistence_.shape == (k,)
    tree = c.condensed_tree_.to_numpy()
    assert tree.dtype.names == ("parent", "child", "lambda_val", "child_size")
    assert tree["parent"].min() == n
    slt = c.single_linkage_tree_.to_numpy()
    assert slt.shape == (n - 1, 4) and np.all(np.diff(slt[:, 2]) >= 0)
    assert len(c.exemplars_) == k and all(e.shape[1] == x.shape[1] for e in c.exemplars_)
    pytest.importorskip("pandas")
    assert list(c.condensed_tree_.to_pandas().columns) == ["parent", "child", "lambda_val",
                                                           "child_size"]
    assert len(c.single_linkage_tree_.to_pandas()) == n - 1
    assert not hasattr(c, "minimum_spanning_tree_")
    assert ds3d.HDBSCAN(gen_min_span_tree=True).fit(x).minimum_spanning_tree_.to_numpy().shape \
        == (n - 1, 3)


def test_estimator_protocol():
    c = ds3d.HDBSCAN(min_cluster_size=7)
    params = c.get_params()
    assert params["min_cluster_size"] == 7 and params["metric"] == "euclidean"
    clone = type(c)(**params)
    assert clone.get_params() == params
    assert c.set_params(min_samples=3, cluster_selection_method="leaf") is c
    assert c.min_samples == 3
    assert "min_samples=3" in repr(c)
    with pytest.raises(ValueError, match="invalid parameter 'nope'"):
        c.set_params(nope=1)
    rng = np.random.default_rng(0)
    x = np.vstack([rng.normal(m, 0.3, size=(80, 2)) for m in (0.0, 5.0)])
    labels = ds3d.HDBSCAN(min_cluster_size=10).fit_predict(x)
    assert labels.max() == 1
    # generate_prediction_data after the fact gives the same predictions as at fit time.
    late = ds3d.HDBSCAN(min_cluster_size=10).fit(x)
    with pytest.raises(ValueError, match="no prediction data"):
        ds3d.approximate_predict(late, x[:3])
    late.generate_prediction_data()
    early = ds3d.HDBSCAN(min_cluster_size=10, prediction_data=True).fit(x)
    np.testing.assert_array_equal(ds3d.approximate_predict(late, x)[0],
                                  ds3d.approximate_predict(early, x)[0])
    # Algorithms and thread counts give the same partition on tie-free data.
    for algorithm in ("best", "generic", "boruvka_kdtree", "boruvka_balltree"):
        np.testing.assert_array_equal(
            ds3d.HDBSCAN(min_cluster_size=10, algorithm=algorithm,
                         core_dist_n_jobs=-1).fit_predict(x), labels)


def test_public_names():
    for name in ("HDBSCAN", "approximate_predict", "membership_vector",
                 "all_points_membership_vectors", "hdbscan", "HdbscanPredictor", "__version__"):
        assert name in ds3d.__all__
        assert hasattr(ds3d, name)
    doc = ds3d.HDBSCAN.__doc__
    for word in ("Parameters", "Attributes", "Examples", "min_cluster_size", "labels_",
                 "prediction_data"):
        assert word in doc


@pytest.mark.parametrize("kwargs, match", [
    ({"metric": "manhattan"}, "metric='manhattan' is not supported"),
    ({"alpha": 1.3}, "alpha=1.3"),
    ({"algorithm": "fast"}, "algorithm must be one of"),
    ({"cluster_selection_method": "best"}, "cluster_selection_method"),
    ({"min_samples": 0}, "min_samples"),
    ({"min_cluster_size": 1}, "min_cluster_size"),
    ({"cluster_selection_persistence": 0.5}, "cluster_selection_persistence"),
])
def test_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ds3d.HDBSCAN(**kwargs).fit(np.zeros((10, 2)))


def test_bad_points():
    with pytest.raises(ValueError, match="row 3 column 1"):
        x = np.zeros((10, 2))
        x[3, 1] = np.inf
        ds3d.HDBSCAN().fit(x)
    with pytest.raises(ValueError, match=r"\(n, d\) array"):
        ds3d.HDBSCAN().fit(np.zeros(5))
    c = ds3d.HDBSCAN(min_cluster_size=5, prediction_data=True).fit(
        np.random.default_rng(1).normal(size=(50, 3)))
    with pytest.raises(ValueError, match=r"\(m, 3\) array"):
        ds3d.approximate_predict(c, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="not finite"):
        ds3d.membership_vector(c, [[0.0, np.nan, 0.0]])
