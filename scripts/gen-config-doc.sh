#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Regenerates the key table at the end of docs/configuration.md (after its "generated" marker)
# from the key table compiled into ds3d (ds3d::slam::config_markdown()); config_test checks it.
# Usage: scripts/gen-config-doc.sh [BUILD_DIR]   (default build; needs the Python extension)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
doc=docs/configuration.md
marker='<!-- generated: ds3d-slam --dump-config -->'
grep -qF "$marker" "$doc" || { echo "gen-config-doc: no marker line in $doc" >&2; exit 1; }
table=$(PYTHONPATH="$build/python" "${PYTHON:-/usr/bin/python3}" -c \
  'import sys, ds3d._ds3d as m; sys.stdout.write(m._config_markdown())')
{
  sed "/$(printf '%s' "$marker" | sed 's/[]\/$*.^[]/\\&/g')/q" "$doc"
  echo
  printf '%s\n' "$table"
} > "$doc.tmp"
mv "$doc.tmp" "$doc"
echo "gen-config-doc: $(grep -c '^| `' "$doc") keys written to $doc"
