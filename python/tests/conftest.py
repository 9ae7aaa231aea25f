# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Puts the build-tree package (build/python, or $DS3D_BUILD_DIR/python) first on sys.path.

Set DS3D_TEST_INSTALLED=1 to test an installed ds3d (pip install) instead of the build tree.
"""
import os
import pathlib
import sys

_root = pathlib.Path(__file__).resolve().parents[2]
_build = pathlib.Path(os.environ.get("DS3D_BUILD_DIR", _root / "build")) / "python"
if not os.environ.get("DS3D_TEST_INSTALLED") and (_build / "ds3d").is_dir():
    sys.path.insert(0, str(_build))
