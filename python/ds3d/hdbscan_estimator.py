# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""``ds3d.HDBSCAN``: a drop-in for the clustering API of the ``hdbscan`` library (0.8.43).

The estimator, ``approximate_predict``, ``membership_vector`` and
``all_points_membership_vectors`` follow the reference's names, conventions and results; the work
is done in C++ (ds3d/cluster/hdbscan.hpp, ds3d/cluster/hdbscan_predict.hpp). scikit-learn is not
needed: ``get_params`` / ``set_params`` follow its estimator protocol.
"""
import inspect
import math

import numpy as np

from . import _ds3d
from .hdbscan import CONDENSED_TREE_DTYPE

__all__ = ["HDBSCAN", "CondensedTree", "SingleLinkageTree", "MinimumSpanningTree",
           "approximate_predict", "membership_vector", "all_points_membership_vectors"]

# Reference algorithm names -> ours. Every one gives the exact MST; 'best' picks by size.
_ALGORITHMS = {
    "best": _ds3d.MstAlgorithm.auto, "auto": _ds3d.MstAlgorithm.auto,
    "generic": _ds3d.MstAlgorithm.prims, "prims_kdtree": _ds3d.MstAlgorithm.prims,
    "prims_balltree": _ds3d.MstAlgorithm.prims, "prims": _ds3d.MstAlgorithm.prims,
    "boruvka_kdtree": _ds3d.MstAlgorithm.boruvka,
    "boruvka_balltree": _ds3d.MstAlgorithm.boruvka, "boruvka": _ds3d.MstAlgorithm.boruvka,
}
_METHODS = {"eom": _ds3d.ClusterSelection.eom, "leaf": _ds3d.ClusterSelection.leaf}


def _pandas(what):
    try:
        import pandas  # noqa: PLC0415  (optional dependency)
    except ImportError as e:
        raise ImportError(f"ds3d.{what}.to_pandas() needs pandas, which is not installed") from e
    return pandas


class CondensedTree:
    """The condensed cluster hierarchy (reference ``hdbscan.plots.CondensedTree``).

    Rows (parent, child, lambda_val, child_size): ids < n are points, the root cluster is n.
    """

    def __init__(self, raw_tree):
        self._raw_tree = raw_tree

    def to_numpy(self):
        """Structured array with fields parent, child, lambda_val, child_size (a copy)."""
        return self._raw_tree.copy()

    def to_pandas(self):
        """DataFrame with columns parent, child, lambda_val, child_size (needs pandas)."""
        return _pandas("CondensedTree").DataFrame(self._raw_tree)

    def __len__(self):
        return len(self._raw_tree)

    def __repr__(self):
        return f"CondensedTree({len(self._raw_tree)} rows)"


class SingleLinkageTree:
    """The single-linkage hierarchy (reference ``hdbscan.plots.SingleLinkageTree``): (n-1) x 4
    float64 in scipy linkage layout (left, right, distance, size); row i creates node n + i."""

    def __init__(self, linkage):
        self._linkage = linkage

    def to_numpy(self):
        """(n-1, 4) float64 array: left, right, distance, size (a copy)."""
        return self._linkage.copy()

    def to_pandas(self):
        """DataFrame with columns parent, left_child, right_child, distance, size (needs pandas),
        as the reference writes it."""
        pd = _pandas("SingleLinkageTree")
        n = len(self._linkage) + 1
        return pd.DataFrame({
            "parent": np.arange(n, 2 * n - 1), "left_child": self._linkage[:, 0].astype(np.intp),
            "right_child": self._linkage[:, 1].astype(np.intp),
            "distance": self._linkage[:, 2], "size": self._linkage[:, 3].astype(np.intp)})

    def __len__(self):
        return len(self._linkage)

    def __repr__(self):
        return f"SingleLinkageTree({len(self._linkage)} merges)"


class MinimumSpanningTree:
    """The mutual-reachability MST (reference ``hdbscan.plots.MinimumSpanningTree``), set when
    ``gen_min_span_tree=True``: (n-1) x 3 float64 (from, to, distance), sorted by distance."""

    def __init__(self, mst, data):
        self._mst = mst
        self._data = data

    def to_numpy(self):
        """(n-1, 3) float64 array: from, to, distance (a copy)."""
        return self._mst.copy()

    def to_pandas(self):
        """DataFrame with columns from, to, distance (needs pandas)."""
        return _pandas("MinimumSpanningTree").DataFrame(
            {"from": self._mst[:, 0], "to": self._mst[:, 1], "distance": self._mst[:, 2]})

    def __len__(self):
        return len(self._mst)


class HDBSCAN:
    """HDBSCAN* clustering with the interface of ``hdbscan.HDBSCAN`` (hdbscan 0.8.43).

    Exact HDBSCAN* of an (n, d) float array, Euclidean. For ``algorithm`` 'best', 'generic' and
    'prims_*' below 3000 points the partition, probabilities, outlier scores and trees equal the
    reference's ``algorithm='prims_kdtree', approx_min_span_tree=False`` fit, equal-weight ties
    included; prediction (:func:`approximate_predict`, :func:`membership_vector`,
    :func:`all_points_membership_vectors`) equals ``hdbscan.prediction``.

    Parameters
    ----------
    min_cluster_size : int, default 5
        Smallest group counted as a cluster, >= 2.
    min_samples : int or None, default None
        k of the core distance (k-th nearest other point), >= 1; None = min_cluster_size.
    cluster_selection_epsilon : float, default 0.0
        Clusters born below this distance [data units] are merged upwards, >= 0.
    max_cluster_size : int, default 0
        EOM: never select a cluster larger than this; 0 = no limit.
    metric : str, default 'euclidean'
        Only 'euclidean'; any other value raises ValueError.
    alpha : float, default 1.0
        Distance scaling of robust single linkage; only 1.0 is supported.
    p : None
        Minkowski power; only None (it applies to metric='minkowski', which is not supported).
    algorithm : str, default 'best'
        'best' (Prim below 3000 points, KD-tree Boruvka above), 'generic', 'prims_kdtree',
        'prims_balltree' (Prim), 'boruvka_kdtree', 'boruvka_balltree' (Boruvka); also ds3d's
        'auto', 'prims', 'boruvka'. All build the exact MST (the reference's Boruvka with
        ``approx_min_span_tree=True`` does not), so results differ from the reference at most in
        how equal MST weights are ordered, and only with Boruvka.
    leaf_size : int, default 40
        Accepted for compatibility; ds3d's KD-trees choose their own leaf sizes.
    memory : None or str, default None
        Accepted for compatibility (no caching).
    approx_min_span_tree : bool, default True
        Accepted for compatibility; the MST is always exact.
    gen_min_span_tree : bool, default False
        Also set ``minimum_spanning_tree_``.
    core_dist_n_jobs : int, default 4
        Threads for the core distances and Boruvka; < 0 = all cores. Results do not depend on it.
    cluster_selection_method : {'eom', 'leaf'}, default 'eom'
        Excess of mass, or the leaves of the cluster tree.
    allow_single_cluster : bool, default False
        Let the root be selected as the only cluster.
    prediction_data : bool, default False
        Build the prediction data during fit (see :meth:`generate_prediction_data`).
    cluster_selection_persistence : float, default 0.0
        Only 0.0 is supported.
    cluster_selection_epsilon_max : float, default inf
        Only inf is supported.
    match_reference_implementation : bool, default False
        Only False is supported.
    branch_detection_data : bool, default False
        Only False is supported.

    Attributes
    ----------
    labels_ : ndarray of int32, shape (n,)
        Cluster label per point, 0..k-1, or -1 for noise.
    probabilities_ : ndarray of float64, shape (n,)
        Membership strength in [0, 1]; 0 for noise.
    outlier_scores_ : ndarray of float64, shape (n,)
        GLOSH outlier score in [0, 1] (NaN only for exact duplicates, as in the reference).
    cluster_persistence_ : ndarray of float64, shape (k,)
        Persistence of each selected cluster, in label order.
    condensed_tree_ : CondensedTree
        ``.to_numpy()``: structured array (parent, child, lambda_val, child_size).
    single_linkage_tree_ : SingleLinkageTree
        ``.to_numpy()``: (n-1, 4) array in scipy linkage layout.
    minimum_spanning_tree_ : MinimumSpanningTree
        Only with ``gen_min_span_tree=True``.
    prediction_data_ : ds3d.HdbscanPredictor or None
        Set by ``prediction_data=True`` or :meth:`generate_prediction_data`.
    exemplars_ : list of ndarray
        Per cluster, the exemplar points (needs prediction data).
    n_features_in_ : int
        Number of columns seen by fit.

    Raises
    ------
    ValueError
        From fit, for an unsupported or bad parameter (the message names it and its value), an
        input that is not an (n, d) array, or a non-finite coordinate (the reference marks such
        rows as noise instead). TypeError for an unknown keyword.

    Examples
    --------
    >>> import numpy as np, ds3d
    >>> rng = np.random.default_rng(0)
    >>> X = np.vstack([rng.normal(c, 0.3, size=(100, 2)) for c in (0.0, 4.0)])
    >>> clusterer = ds3d.HDBSCAN(min_cluster_size=15, prediction_data=True).fit(X)
    >>> int(clusterer.labels_.max()) + 1
    2
    >>> labels, strengths = ds3d.approximate_predict(clusterer, [[0.1, 0.0], [4.0, 4.1]])
    >>> labels.tolist() == [clusterer.labels_[0], clusterer.labels_[100]]
    True
    >>> ds3d.membership_vector(clusterer, [[0.1, 0.0]]).shape
    (1, 2)
    """

    _estimator_type = "clusterer"  # scikit-learn's marker for clustering estimators

    def __init__(self, min_cluster_size=5, min_samples=None, cluster_selection_epsilon=0.0,
                 max_cluster_size=0, metric="euclidean", alpha=1.0, p=None, algorithm="best",
                 leaf_size=40, memory=None, approx_min_span_tree=True, gen_min_span_tree=False,
                 core_dist_n_jobs=4, cluster_selection_method="eom", allow_single_cluster=False,
                 prediction_data=False, cluster_selection_persistence=0.0,
                 cluster_selection_epsilon_max=float("inf"), match_reference_implementation=False,
                 branch_detection_data=False):
        self.min_cluster_size = min_cluster_size
        self.min_samples = min_samples
        self.cluster_selection_epsilon = cluster_selection_epsilon
        self.max_cluster_size = max_cluster_size
        self.metric = metric
        self.alpha = alpha
        self.p = p
        self.algorithm = algorithm
        self.leaf_size = leaf_size
        self.memory = memory
        self.approx_min_span_tree = approx_min_span_tree
        self.gen_min_span_tree = gen_min_span_tree
        self.core_dist_n_jobs = core_dist_n_jobs
        self.cluster_selection_method = cluster_selection_method
        self.allow_single_cluster = allow_single_cluster
        self.prediction_data = prediction_data
        self.cluster_selection_persistence = cluster_selection_persistence
        self.cluster_selection_epsilon_max = cluster_selection_epsilon_max
        self.match_reference_implementation = match_reference_implementation
        self.branch_detection_data = branch_detection_data
        self.prediction_data_ = None

    # scikit-learn estimator protocol -------------------------------------------------------
    @classmethod
    def _get_param_names(cls):
        sig = inspect.signature(cls.__init__)
        return sorted(n for n in sig.parameters if n != "self")

    def get_params(self, deep=True):  # noqa: ARG002  (no nested estimators)
        """Constructor parameters as a dict (scikit-learn protocol)."""
        return {name: getattr(self, name) for name in self._get_param_names()}

    def set_params(self, **params):
        """Sets constructor parameters; returns self. Raises ValueError for an unknown name."""
        valid = self._get_param_names()
        for name, value in params.items():
            if name not in valid:
                raise ValueError(f"ds3d.HDBSCAN.set_params: invalid parameter {name!r} "
                                 f"(valid: {', '.join(valid)})")
            setattr(self, name, value)
        return self

    def __repr__(self):
        defaults = type(self)().get_params()
        changed = [f"{k}={v!r}" for k, v in self.get_params().items() if v != defaults[k]]
        return f"HDBSCAN({', '.join(changed)})"

    # fitting -------------------------------------------------------------------------------
    def _check_unsupported(self):
        fixed = [("metric", "euclidean"), ("alpha", 1.0), ("p", None),
                 ("cluster_selection_persistence", 0.0),
                 ("cluster_selection_epsilon_max", float("inf")),
                 ("match_reference_implementation", False), ("branch_detection_data", False)]
        for name, only in fixed:
            value = getattr(self, name)
            if value != only and not (isinstance(value, float) and isinstance(only, float)
                                      and math.isinf(value) and math.isinf(only)):
                raise ValueError(f"ds3d.HDBSCAN: {name}={value!r} is not supported "
                                 f"(only {only!r})")

    def _params(self):
        self._check_unsupported()
        if self.algorithm not in _ALGORITHMS:
            raise ValueError(f"ds3d.HDBSCAN: algorithm must be one of "
                             f"{', '.join(sorted(_ALGORITHMS))} (got {self.algorithm!r})")
        if self.cluster_selection_method not in _METHODS:
            raise ValueError("ds3d.HDBSCAN: cluster_selection_method must be 'eom' or 'leaf' "
                             f"(got {self.cluster_selection_method!r})")
        if self.min_samples is not None and int(self.min_samples) < 1:
            raise ValueError(f"ds3d.HDBSCAN: min_samples must be None or >= 1 "
                             f"(got {self.min_samples!r})")
        prm = _ds3d.HdbscanParams()
        prm.min_cluster_size = int(self.min_cluster_size)
        prm.min_samples = 0 if self.min_samples is None else int(self.min_samples)
        prm.cluster_selection_method = _METHODS[self.cluster_selection_method]
        prm.allow_single_cluster = bool(self.allow_single_cluster)
        prm.cluster_selection_epsilon = float(self.cluster_selection_epsilon)
        prm.max_cluster_size = int(self.max_cluster_size)
        prm.algorithm = _ALGORITHMS[self.algorithm]
        jobs = int(self.core_dist_n_jobs)
        prm.num_threads = 0 if jobs < 0 else max(jobs, 1)
        prm.reference_tie_order = True  # Prim: equal weights ordered as the reference orders them
        prm.validate()
        return prm

    def fit(self, X, y=None):  # noqa: ARG002  (sklearn signature)
        """Clusters X, an (n, d) array-like of finite floats; returns self."""
        prm = self._params()
        x = np.ascontiguousarray(X, dtype=np.float64)
        if x.ndim != 2:
            raise ValueError(f"ds3d.HDBSCAN.fit: X must be an (n, d) array (got shape {x.shape})")
        raw = _ds3d._hdbscan(x, prm, [])
        parent, child, lam, size = raw.condensed_tree_columns
        tree = np.empty(len(parent), dtype=CONDENSED_TREE_DTYPE)
        tree["parent"], tree["child"], tree["lambda_val"], tree["child_size"] = \
            parent, child, lam, size
        self._raw_data, self._raw_fit, self._fit_params = x, raw, prm
        self.n_features_in_ = x.shape[1]
        self.labels_ = raw.labels
        self.probabilities_ = raw.probabilities
        self.outlier_scores_ = raw.outlier_scores
        self.cluster_persistence_ = raw.cluster_persistence
        self.condensed_tree_ = CondensedTree(tree)
        self.single_linkage_tree_ = SingleLinkageTree(raw.single_linkage_tree)
        if self.gen_min_span_tree:
            self.minimum_spanning_tree_ = MinimumSpanningTree(raw.min_spanning_tree, x)
        self.prediction_data_ = None
        if self.prediction_data:
            self.generate_prediction_data()
        return self

    def fit_predict(self, X, y=None):
        """fit(X) and return ``labels_``."""
        return self.fit(X, y).labels_

    def generate_prediction_data(self):
        """Builds ``prediction_data_`` (KD-tree, core distances, exemplars) for
        :func:`approximate_predict` and :func:`membership_vector` after a fit."""
        if not hasattr(self, "_raw_fit"):
            raise ValueError("ds3d.HDBSCAN.generate_prediction_data: call fit() first")
        self.prediction_data_ = _ds3d.HdbscanPredictor(self._raw_data, self._raw_fit,
                                                       self._fit_params,
                                                       self._fit_params.num_threads)
        return self.prediction_data_

    @property
    def exemplars_(self):
        """Per cluster, the exemplar points (rows of the fitted data); needs prediction data."""
        pd = _require_prediction_data(self, "HDBSCAN.exemplars_")
        return [self._raw_data[pd.exemplars(label)] for label in range(pd.num_labels)]


def _require_prediction_data(clusterer, fn):
    pd = getattr(clusterer, "prediction_data_", None)
    if pd is None:
        raise ValueError(f"ds3d.{fn}: the clusterer has no prediction data; fit it with "
                         "prediction_data=True or call generate_prediction_data()")
    return pd


def _query(clusterer, points, fn):
    pd = _require_prediction_data(clusterer, fn)
    q = np.ascontiguousarray(points, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != pd.dim:
        raise ValueError(f"ds3d.{fn}: points must be an (m, {pd.dim}) array like the fitted data "
                         f"(got shape {q.shape})")
    return pd, q


def approximate_predict(clusterer, points_to_predict):
    """Labels and membership strengths of new points in a fitted clustering, as
    ``hdbscan.approximate_predict``: (labels int32 (m,), probabilities float64 (m,)); -1 / 0
    for noise. The clustering itself is not changed.

    Raises ValueError when the clusterer has no prediction data or the points have the wrong
    shape or a non-finite coordinate."""
    pd, q = _query(clusterer, points_to_predict, "approximate_predict")
    return pd.approximate_predict(q)


def membership_vector(clusterer, points_to_predict):
    """Soft cluster membership of new points, as ``hdbscan.membership_vector``: float64 (m, k),
    column j the probability of cluster j; rows sum to the probability of being in any cluster."""
    pd, q = _query(clusterer, points_to_predict, "membership_vector")
    return pd.membership_vector(q)


def all_points_membership_vectors(clusterer):
    """Soft cluster membership of every fitted point, as
    ``hdbscan.all_points_membership_vectors``: float64 (n, k)."""
    return _require_prediction_data(clusterer, "all_points_membership_vectors") \
        .all_points_membership_vectors()
