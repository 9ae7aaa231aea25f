# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d: dynamic-feature removal for RGB-D SLAM (the 3DS-SLAM method as a toolkit).

The compiled core lives in ``ds3d._ds3d`` (pybind11); this package re-exports it and adds
pure-Python conveniences. C++ exceptions map to Python as follows:
``ds3d::InvalidArgument`` -> ``ValueError``; ``ds3d::IoError`` and ``ds3d::NumericalError`` ->
``RuntimeError``.
"""
from . import _ds3d
from ._ds3d import __version__  # noqa: F401
from ._ds3d import *  # noqa: F401,F403
from . import htx  # noqa: F401  (lazy: torch is imported on first use)
from .hdbscan import HdbscanResult, hdbscan, hdbscan_precomputed  # noqa: F401
from .hdbscan_estimator import (HDBSCAN, CondensedTree, MinimumSpanningTree,  # noqa: F401
                                SingleLinkageTree, all_points_membership_vectors,
                                approximate_predict, membership_vector)
from .config import SlamConfig, config_keys  # noqa: F401
from .slam import Slam, SlamResult, make_dynamic_source, run_slam  # noqa: F401

from . import synth  # noqa: F401

# The public API: the compiled names (which depend on the components built) plus the Python ones.
__all__ = sorted({"__version__", "htx", "synth", "HdbscanResult", "hdbscan", "hdbscan_precomputed",
                  "HDBSCAN", "CondensedTree", "SingleLinkageTree", "MinimumSpanningTree",
                  "approximate_predict", "membership_vector", "all_points_membership_vectors",
                  "SlamConfig", "config_keys", "make_dynamic_source", "run_slam", "Slam",
                  "SlamResult"}
                 | {n for n in dir(_ds3d) if not n.startswith("_")})
