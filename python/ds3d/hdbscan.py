# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""HDBSCAN* with the keyword names of the reference ``hdbscan`` library (see ds3d/cluster/hdbscan.hpp).

``ds3d.hdbscan(points, ...)`` returns an :class:`HdbscanResult` whose partitions, probabilities
and outlier scores match hdbscan 0.8.43 (algorithm='prims_kdtree', i.e. exact HDBSCAN*).
"""
from dataclasses import dataclass

import numpy as np

from . import _ds3d

__all__ = ["hdbscan", "hdbscan_precomputed", "HdbscanResult", "CONDENSED_TREE_DTYPE"]

#: dtype of :attr:`HdbscanResult.condensed_tree` (the reference's ``condensed_tree_`` layout).
CONDENSED_TREE_DTYPE = np.dtype(
    [("parent", np.intp), ("child", np.intp), ("lambda_val", np.float64), ("child_size", np.intp)]
)


@dataclass(frozen=True)
class HdbscanResult:
    """Clustering of n points.

    labels: int32 (n,), cluster id or -1 for noise. probabilities: float64 (n,), membership
    strength in [0, 1]. outlier_scores: float64 (n,), GLOSH (NaN only for exact duplicates, as in
    the reference). condensed_tree: structured array (parent, child, lambda_val, child_size).
    single_linkage_tree: (n-1, 4) float64, scipy linkage layout. cluster_persistence: float64
    per selected cluster. min_spanning_tree: (n-1, 3) float64 (from, to, weight).
    core_distances: float64 (n,). num_clusters / min_samples_effective: ints.
    """

    labels: np.ndarray
    probabilities: np.ndarray
    outlier_scores: np.ndarray
    condensed_tree: np.ndarray
    single_linkage_tree: np.ndarray
    cluster_persistence: np.ndarray
    min_spanning_tree: np.ndarray
    core_distances: np.ndarray
    num_clusters: int
    min_samples_effective: int


_INT32_MAX = 2**31 - 1


def _int32(name, value):
    """``value`` as a Python int that fits the C++ ``int`` field, else ValueError naming it."""
    try:
        v = int(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"ds3d.hdbscan: {name} must be an integer (got {value!r})") from None
    if not -_INT32_MAX - 1 <= v <= _INT32_MAX:
        raise ValueError(f"ds3d.hdbscan: {name} must fit a 32-bit int, at most {_INT32_MAX} "
                         f"(got {value!r})")
    return v


def _params(min_cluster_size, min_samples, cluster_selection_method, allow_single_cluster,
            cluster_selection_epsilon, max_cluster_size, algorithm, num_threads):
    p = _ds3d.HdbscanParams()
    if min_samples is not None and _int32("min_samples", min_samples) < 1:
        raise ValueError(f"ds3d.hdbscan: min_samples must be None or >= 1 (got {min_samples})")
    methods = {"eom": _ds3d.ClusterSelection.eom, "leaf": _ds3d.ClusterSelection.leaf}
    if cluster_selection_method not in methods:
        raise ValueError("ds3d.hdbscan: cluster_selection_method must be 'eom' or 'leaf' "
                         f"(got {cluster_selection_method!r})")
    algorithms = {"auto": _ds3d.MstAlgorithm.auto, "prims": _ds3d.MstAlgorithm.prims,
                  "boruvka": _ds3d.MstAlgorithm.boruvka}
    if algorithm not in algorithms:
        raise ValueError("ds3d.hdbscan: algorithm must be 'auto', 'prims' or 'boruvka' "
                         f"(got {algorithm!r})")
    p.min_cluster_size = _int32("min_cluster_size", min_cluster_size)
    p.min_samples = 0 if min_samples is None else _int32("min_samples", min_samples)
    p.cluster_selection_method = methods[cluster_selection_method]
    p.allow_single_cluster = bool(allow_single_cluster)
    p.cluster_selection_epsilon = float(cluster_selection_epsilon)
    p.max_cluster_size = _int32("max_cluster_size", max_cluster_size)
    p.algorithm = algorithms[algorithm]
    p.num_threads = _int32("num_threads", num_threads)
    return p


def _wrap(raw):
    parent, child, lam, size = raw.condensed_tree_columns
    tree = np.empty(len(parent), dtype=CONDENSED_TREE_DTYPE)
    tree["parent"], tree["child"], tree["lambda_val"], tree["child_size"] = parent, child, lam, size
    return HdbscanResult(
        labels=raw.labels, probabilities=raw.probabilities, outlier_scores=raw.outlier_scores,
        condensed_tree=tree, single_linkage_tree=raw.single_linkage_tree,
        cluster_persistence=raw.cluster_persistence, min_spanning_tree=raw.min_spanning_tree,
        core_distances=raw.core_distances, num_clusters=raw.num_clusters,
        min_samples_effective=raw.min_samples_effective)


def hdbscan(points, min_cluster_size=5, min_samples=None, cluster_selection_method="eom",
            allow_single_cluster=False, cluster_selection_epsilon=0.0, max_cluster_size=0,
            algorithm="auto", num_threads=1, *, scale=None):
    """HDBSCAN* of an (n, d) array (Euclidean). ``scale``: optional per-column weights (> 0)
    multiplied into the coordinates first, e.g. ``[1, 1, 100]`` for (u px, v px, depth m).
    Raises ValueError for bad parameters or non-finite points (the message names the row)."""
    x = np.ascontiguousarray(points, dtype=np.float64)
    if x.ndim == 1:
        x = x.reshape(-1, 1)
    if x.ndim != 2:
        raise ValueError(f"ds3d.hdbscan: points must be an (n, d) array (got shape {x.shape})")
    p = _params(min_cluster_size, min_samples, cluster_selection_method, allow_single_cluster,
                cluster_selection_epsilon, max_cluster_size, algorithm, num_threads)
    s = [] if scale is None else [float(v) for v in np.asarray(scale, dtype=np.float64).ravel()]
    return _wrap(_ds3d._hdbscan(x, p, s))


def hdbscan_precomputed(distances, min_cluster_size=5, min_samples=None,
                        cluster_selection_method="eom", allow_single_cluster=False,
                        cluster_selection_epsilon=0.0, max_cluster_size=0, num_threads=1):
    """HDBSCAN* of a symmetric (n, n) distance matrix (zero diagonal, finite, >= 0)."""
    d = np.ascontiguousarray(distances, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"ds3d.hdbscan_precomputed: distances must be (n, n) (got shape {d.shape})")
    p = _params(min_cluster_size, min_samples, cluster_selection_method, allow_single_cluster,
                cluster_selection_epsilon, max_cluster_size, "prims", num_threads)
    return _wrap(_ds3d._hdbscan_precomputed(d, p))
