#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Real-data figures of the dynamic-feature removal (docs/dynamic.md, docs/benchmarks.md):
# ds3d-slam with --dynamic none and geometric on bonn_crowd_first300 and tum_fr1_xyz_first400,
# ATE RMSE from ds3d-eval against the raw groundtruth.txt (TUM evaluate_ate.py rules: 0.02 s
# association, Horn alignment without scale), fps and detect/filter times from --stats.
# With DS3D_EVAL_SYNTH=1 also the synthetic walking_*/sitting_* scenarios (ds3d-synth, 240 frames,
# seed 1), ATE against the generator's groundtruth.
# Usage: scripts/eval-dynamic.sh [BUILD_DIR] ; data from $DS3D_DATA_DIR (default ../shared/data).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$here/build}"
data="${DS3D_DATA_DIR:-$here/../shared/data}"
out="${DS3D_EVAL_OUT:-$build/eval-dynamic}"
synth="${DS3D_EVAL_SYNTH:-0}"
if [[ ! -d "$data/bonn_crowd_first300" && ! -d "$data/tum_fr1_xyz_first400" && "$synth" != 1 ]]; then
  echo "eval-dynamic: no recorded data under $data (set DS3D_DATA_DIR); skipping"
  exit 0
fi
mkdir -p "$out"
eval_bin="$build/bin/ds3d-eval"
for b in "$build/bin/ds3d-slam" "$eval_bin"; do
  [[ -x "$b" ]] || { echo "eval-dynamic: $b not built (cmake --build $build --target ds3d-slam ds3d-eval)" >&2; exit 1; }
done
ate() {  # ate EST GT -> "ATE_RMSE PAIRS" from ds3d-eval (SE(3) alignment, 0.02 s association)
  "$eval_bin" ate "$2" "$1" --json |
    /usr/bin/python3 -c 'import json,sys; r=json.load(sys.stdin); print("%.4f %d" % (r["rmse"], r["compared_pose_pairs"]))'
}
# One table row: row LABEL DATASET_DIR DYNAMIC OUT_STEM (runs ds3d-slam, scores it, reads its stats).
row() {
  local label=$1 dir=$2 dyn=$3 stem=$4 rmse n fps
  "$build/bin/ds3d-slam" "$dir" --dynamic "$dyn" --out "$stem.txt" --stats "$stem.json" --quiet
  read -r rmse n < <(ate "$stem.txt" "$dir/groundtruth.txt")
  fps=$(/usr/bin/python3 -c "import json,sys; s=json.load(open(sys.argv[1])); print(f\"{s['tracked_frames']}/{s['frames']} {s['fps_median']:.1f} {s['stages']['detect']['median_ms']:.2f} {s['stages']['filter']['median_ms']:.2f}\")" "$stem.json")
  printf "| %s | %s | %s | %s | %s | %s | %s | %s |\n" "$label" "$dyn" "$rmse" "$n" ${fps}
}
printf "| sequence | --dynamic | ATE RMSE [m] | pairs | tracked | fps median | detect median [ms] | filter median [ms] |\n|---|---|---|---|---|---|---|---|\n"
for seq in bonn_crowd_first300 tum_fr1_xyz_first400; do
  [[ -d "$data/$seq" ]] || { echo "| $seq | (absent) | | | | | | |"; continue; }
  for dyn in none geometric; do
    row "$seq" "$data/$seq" "$dyn" "$out/${seq}_${dyn}"
  done
done
if [[ "$synth" == 1 ]]; then
  [[ -x "$build/bin/ds3d-synth" ]] || { echo "eval-dynamic: $build/bin/ds3d-synth not built" >&2; exit 1; }
  printf "\n| synthetic (240 frames, seed 1) | --dynamic | ATE RMSE [m] | pairs | tracked | fps median | detect median [ms] | filter median [ms] |\n|---|---|---|---|---|---|---|---|\n"
  for sc in walking_xyz walking_static walking_halfsphere walking_rpy sitting_static sitting_xyz; do
    "$build/bin/ds3d-synth" "$out/synth_$sc" --scenario "$sc" --frames 240 --seed 1 --overwrite >/dev/null
    for dyn in none geometric; do
      row "$sc" "$out/synth_$sc" "$dyn" "$out/synth_${sc}_${dyn}"
    done
  done
fi
