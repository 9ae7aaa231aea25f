#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# scripts/format.sh fix|check|tidy [BUILD_DIR] — clang-format over our C++ sources, or clang-tidy
# over the compiled sources using BUILD_DIR/compile_commands.json.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-check}
mapfile -t files < <(git ls-files -- 'include/*.hpp' 'src/*.cpp' 'src/*.hpp' 'tests/*.cpp' \
  'tests/*.hpp' 'bench/*.cpp' 'bench/*.hpp' 'python/src/*.cpp' 'examples/*.cpp' 'examples/*.hpp')
case "$mode" in
  fix) clang-format -i "${files[@]}" ;;
  check)
    clang-format --dry-run --Werror "${files[@]}"
    echo "format-check: ${#files[@]} files clean" ;;
  tidy)
    build=${2:-build}
    mapfile -t srcs < <(git ls-files -- 'src/*.cpp')
    clang-tidy -p "$build" --quiet "${srcs[@]}" ;;
  *) echo "usage: $0 fix|check|tidy [BUILD_DIR]" >&2; exit 2 ;;
esac
