# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""python3 -m ds3d.bench SUITE [...]: the ds3d-bench command (ds3d.bench.cli)."""
import sys

from .cli import main

sys.exit(main())
