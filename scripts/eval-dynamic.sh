#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Real-data figures of the dynamic-feature removal (docs/dynamic.md, docs/benchmarks.md):
# ds3d-slam with --dynamic none and geometric on bonn_crowd_first300 and tum_fr1_xyz_first400,
# ATE RMSE against the raw groundtruth.txt (TUM evaluate_ate.py rules: 0.02 s association,
# Horn alignment without scale), fps and filter time from --stats.
# Usage: scripts/eval-dynamic.sh [BUILD_DIR] ; data from $DS3D_DATA_DIR (default ../shared/data).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$here/build}"
data="${DS3D_DATA_DIR:-$here/../shared/data}"
out="${DS3D_EVAL_OUT:-$build/eval-dynamic}"
if [[ ! -d "$data/bonn_crowd_first300" && ! -d "$data/tum_fr1_xyz_first400" ]]; then
  echo "eval-dynamic: no recorded data under $data (set DS3D_DATA_DIR); skipping"
  exit 0
fi
mkdir -p "$out"
ate() {  # ate EST GT -> ATE RMSE [m]
  /usr/bin/python3 - "$1" "$2" <<'PY'
import sys
import numpy as np
def load(p):
    rows = [l.split() for l in open(p) if l.strip() and not l.startswith('#')]
    return {float(r[0]): np.array([float(x) for x in r[1:4]]) for r in rows}
est, gt = load(sys.argv[1]), load(sys.argv[2])
gk = np.array(sorted(gt))
pairs = []
for t in sorted(est):  # nearest groundtruth stamp within 0.02 s (associate.py rule, greedy)
    j = np.searchsorted(gk, t)
    c = [k for k in (j - 1, j) if 0 <= k < len(gk)]
    k = min(c, key=lambda k: abs(gk[k] - t))
    if abs(gk[k] - t) < 0.02:
        pairs.append((est[t], gt[gk[k]]))
A = np.array([p[0] for p in pairs]).T
B = np.array([p[1] for p in pairs]).T
ma, mb = A.mean(1, keepdims=True), B.mean(1, keepdims=True)
U, _, Vt = np.linalg.svd((B - mb) @ (A - ma).T)
S = np.eye(3)
if np.linalg.det(U @ Vt) < 0:
    S[2, 2] = -1
R = U @ S @ Vt
err = R @ (A - ma) + mb - B
print(f"{np.sqrt((err ** 2).sum(0).mean()):.4f} {len(pairs)}")
PY
}
printf "| sequence | --dynamic | ATE RMSE [m] | pairs | fps median | filter median [ms] |\n|---|---|---|---|---|---|\n"
for seq in bonn_crowd_first300 tum_fr1_xyz_first400; do
  [[ -d "$data/$seq" ]] || { echo "| $seq | (absent) | | | | |"; continue; }
  for dyn in none geometric; do
    "$build/bin/ds3d-slam" "$data/$seq" --dynamic "$dyn" --out "$out/${seq}_${dyn}.txt" \
      --stats "$out/${seq}_${dyn}.json" --quiet
    read -r rmse n < <(ate "$out/${seq}_${dyn}.txt" "$data/$seq/groundtruth.txt")
    fps=$(/usr/bin/python3 -c "import json,sys; s=json.load(open(sys.argv[1])); print(f\"{s['fps_median']:.1f} {s['stages']['filter']['median_ms']:.2f}\")" "$out/${seq}_${dyn}.json")
    printf "| %s | %s | %s | %s | %s | %s |\n" "$seq" "$dyn" "$rmse" "$n" ${fps}
  done
done
