#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Checks that the notebooks under examples/notebooks/ are stored without outputs, then executes
# each one headless against the build tree (Debian python3-nbconvert + python3-ipykernel) and
# writes the rendered HTML to BUILD_DIR/notebooks/<name>.html (the CI artefact).
# Usage: scripts/test-notebook.sh [BUILD_DIR]   (needs the _ds3d module and bin/ds3d-slam built)
#        scripts/test-notebook.sh --check-only   (only the "no outputs committed" check)
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-/usr/bin/python3}

"$PYTHON" - examples/notebooks/*.ipynb <<'PY'
import json, sys
bad = []
for path in sys.argv[1:]:
    nb = json.load(open(path))
    for i, cell in enumerate(nb["cells"]):
        if cell.get("outputs") or cell.get("execution_count") is not None:
            bad.append(f"{path}: cell {i} has outputs or an execution count")
if bad:
    print("test-notebook: notebooks must be committed without outputs:", *bad, sep="\n  ")
    print("  clear them with: jupyter nbconvert --clear-output --inplace <notebook>")
    sys.exit(1)
print(f"test-notebook: {len(sys.argv) - 1} notebook(s) stored without outputs")
PY
[[ "${1:-}" == "--check-only" ]] && exit 0

BUILD_DIR=$(cd "${1:-build}" && pwd)
out="${BUILD_DIR}/notebooks"
mkdir -p "$out"
# Scratch files of the notebooks (generated sequences) go to a folder removed on exit.
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
for nb in examples/notebooks/*.ipynb; do
  start=$(date +%s)
  # Each cell may take at most 240 s; the whole notebook is meant to take < 3 min on 2 cores.
  # nbconvert exits non-zero when a cell raises.
  PYTHONPATH="${BUILD_DIR}/python${PYTHONPATH:+:$PYTHONPATH}" DS3D_BUILD_DIR="${BUILD_DIR}" \
    TMPDIR="$scratch" PYDEVD_DISABLE_FILE_VALIDATION=1 "$PYTHON" -Xfrozen_modules=off \
    -m nbconvert --to html --execute --log-level=WARN --ExecutePreprocessor.timeout=240 \
    --ExecutePreprocessor.kernel_name=python3 --output-dir "$out" "$nb"
  html="$out/$(basename "${nb%.ipynb}").html"
  [[ -s "$html" ]] || { echo "test-notebook: FAILED: no $html" >&2; exit 1; }
  echo "test-notebook: $nb executed in $(( $(date +%s) - start )) s -> $html"
done
