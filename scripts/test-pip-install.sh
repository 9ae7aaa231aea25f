#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Checks the offline pip install: a throw-away venv on Debian's /usr/bin/python3 that sees the
# system site packages (numpy, pybind11, setuptools from Debian; no PyPI), then
#   pip install --no-build-isolation .
# and the package's smoke tests against the installed copy.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-/usr/bin/python3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$PYTHON" -m venv --system-site-packages "$tmp/venv"
CMAKE_BUILD_PARALLEL_LEVEL=${JOBS:-$(nproc)} "$tmp/venv/bin/python" -m pip install \
  --no-build-isolation --no-index --quiet .
cd "$tmp"
DS3D_TEST_INSTALLED=1 "$tmp/venv/bin/python" -m pytest -q -p no:cacheprovider \
  "$OLDPWD/python/tests/errors_test.py"
"$tmp/venv/bin/python" -c "import ds3d, sys; print('pip install OK:', ds3d.__version__, ds3d.__file__)"
