#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Real-data check of the SLAM front-end: runs build/bin/ds3d-slam on the recorded slices under
# $DS3D_DATA_DIR (default ../shared/data next to the repository) and prints ATE with ds3d-eval.
# Skips cleanly (exit 0) when the data is absent. Usage: scripts/eval-real.sh [BUILD_DIR]
# Environment: DS3D_DATA_DIR, OUT_DIR (default build/eval-real), SLAM_ARGS (extra ds3d-slam flags).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$root/build}"
data="${DS3D_DATA_DIR:-$root/../shared/data}"
out="${OUT_DIR:-$build/eval-real}"
slam="$build/bin/ds3d-slam"
eval_bin="$build/bin/ds3d-eval"
for b in "$slam" "$eval_bin"; do
  if [[ ! -x "$b" ]]; then
    echo "eval-real: $b not built (cmake --build $build --target ds3d-slam ds3d-eval)" >&2
    exit 1
  fi
done
if [[ ! -d "$data" ]]; then
  echo "eval-real: SKIPPED: no data directory '$data' (set DS3D_DATA_DIR)"
  exit 0
fi
mkdir -p "$out"
printf '%-24s %-8s %8s %8s %10s %10s %10s\n' sequence dynamic frames tracked "ATE[m]" "fps_med" "track_ms"
for seq in tum_fr1_xyz_first400 bonn_crowd_first300; do
  dir="$data/$seq"
  if [[ ! -f "$dir/rgb.txt" ]]; then
    echo "eval-real: SKIPPED $seq (not in $data)"
    continue
  fi
  # shellcheck disable=SC2086
  "$slam" "$dir" --dynamic none --out "$out/$seq.txt" --stats "$out/$seq.json" --quiet ${SLAM_ARGS:-}
  ate="$("$eval_bin" ate "$dir/groundtruth.txt" "$out/$seq.txt" --json | /usr/bin/python3 -c 'import json,sys; print("%.4f" % json.load(sys.stdin)["rmse"])')"
  /usr/bin/python3 - "$out/$seq.json" "$seq" "$ate" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print("%-24s %-8s %8d %8d %10s %10.1f %10.1f" % (sys.argv[2], s["dynamic"], s["frames"], s["tracked_frames"],
      sys.argv[3], s["fps_median"], s["stages"]["track"]["median_ms"]))
PY
done
echo "(ATE: ds3d-eval ate, SE(3) alignment as evaluate_ate.py; Bonn against its raw groundtruth.txt)"
