# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d-bench: run a suite of sequences x configurations x seeds through ds3d-slam and ds3d-eval,
locally or on a Dask cluster, into one results folder (docs/bench.md).

``python3 -m ds3d.bench SUITE`` or the ``ds3d-bench`` console script; ``main(argv)`` from Python.
"""
from .cli import main, plan  # noqa: F401
from .suite import SuiteError, load_suite  # noqa: F401

__all__ = ["main", "plan", "load_suite", "SuiteError"]
