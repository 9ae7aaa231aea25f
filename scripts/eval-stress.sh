#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Crowd stress suite (docs/eval.md): every crowd_* scenario of ds3d-synth x seeds 1 to 4, plus
# frames 230-299 of the recorded bonn_crowd_first300, through ds3d-slam in every dynamic mode;
# prints one Markdown table (ATE RMSE, worst 3-s window, tracked frames, fps median) and writes it
# with a CSV to --out. Exit 0 when every run completed (figures are not judged), 1 when a run
# crashed (named on stderr; the others still run). --check FILE also compares the ATE with the
# upper bounds of an expectation CSV (bench/stress_expected.csv) and exits 3 on a regression.
#
# Usage: scripts/eval-stress.sh [--quick] [--out DIR] [--jobs N] [--check FILE] [--from CSV]
#   --quick     60 frames, seed 1 only (a smoke run; its rows do not match the expectation file)
#   --out DIR   results (default build/stress)
#   --jobs N    runs in parallel (default 2)
#   --check F   compare with the bounds in F after the run; with --from CSV, compare that CSV only
# Binaries: $DS3D_BIN_DIR (default build/bin) or DS3D_SLAM / DS3D_EVAL / DS3D_SYNTH one by one.
# Recorded data: $DS3D_DATA_DIR (default ../shared/data); the Bonn slice is skipped when absent.
set -uo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
bin="${DS3D_BIN_DIR:-$here/build/bin}"
slam="${DS3D_SLAM:-$bin/ds3d-slam}"
evalb="${DS3D_EVAL:-$bin/ds3d-eval}"
synth="${DS3D_SYNTH:-$bin/ds3d-synth}"
data="${DS3D_DATA_DIR:-$here/../shared/data}"
py=/usr/bin/python3
out="$here/build/stress"
jobs=2
quick=0
check=""
from=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) quick=1 ;;
    --out) out="$2"; shift ;;
    --jobs) jobs="$2"; shift ;;
    --check) check="$2"; shift ;;
    --from) from="$2"; shift ;;
    -h|--help) sed -n '4,17p' "$0"; exit 0 ;;
    *) echo "eval-stress: unknown argument '$1'" >&2; exit 2 ;;
  esac
  shift
done
[[ "$jobs" =~ ^[1-9][0-9]*$ ]] || { echo "eval-stress: --jobs needs a positive integer" >&2; exit 2; }
[[ -z "$check" || -f "$check" ]] || { echo "eval-stress: no expectation file '$check'" >&2; exit 2; }

# compare CSV EXPECTED: rows whose ATE exceeds the bound (or that failed) are regressions.
compare() {
  "$py" - "$1" "$2" <<'EOF'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
bounds = {(r["scenario"], r["seed"], r["mode"], r["frames"]): float(r["ate_max"])
          for r in csv.DictReader(open(sys.argv[2]))}
bad = checked = 0
for r in rows:
    key = (r["scenario"], r["seed"], r["mode"], r["frames"])
    if key not in bounds:
        continue
    checked += 1
    if r["status"] != "ok":
        print(f"REGRESSION {' '.join(key[:3])}: run {r['status']}"); bad += 1
    elif float(r["ate_rmse"]) > bounds[key]:
        print(f"REGRESSION {' '.join(key[:3])}: ATE {float(r['ate_rmse']):.4f} m > bound {bounds[key]:.4f} m")
        bad += 1
print(f"eval-stress --check: {checked} runs compared with {sys.argv[2]}, {bad} regressions")
if checked == 0:
    print("eval-stress --check: no run matched the expectation file (different frames or seeds?)")
    sys.exit(2)
sys.exit(3 if bad else 0)
EOF
}
if [[ -n "$from" ]]; then
  [[ -n "$check" ]] || { echo "eval-stress: --from needs --check" >&2; exit 2; }
  compare "$from" "$check"
  exit $?
fi

for b in "$slam" "$evalb" "$synth"; do
  [[ -x "$b" ]] || { echo "eval-stress: $b not built (cmake --build build --target ds3d-slam ds3d-eval ds3d-synth)" >&2; exit 2; }
done
frames=120
seeds="1 2 3 4"
if [[ $quick == 1 ]]; then frames=60; seeds="1"; fi
scenarios="crowd_cross crowd_board crowd_start crowd_handheld"
modes_real=("none" "geometric" "htx" "htx+geometric" "htx --gate motion" "htx --gate evidence")
mkdir -p "$out/seq" "$out/runs"
rm -f "$out"/runs/*.row
t_start=$(date +%s)

# Runs at most $jobs background jobs at once.
throttle() { while [[ $(jobs -rp | wc -l) -ge $jobs ]]; do wait -n; done; }

# 1. Sequences.
for sc in $scenarios; do
  for seed in $seeds; do
    throttle
    "$synth" "$out/seq/${sc}_$seed" --scenario "$sc" --frames "$frames" --seed "$seed" \
      --detection-errors 0.2,0.1 --overwrite >"$out/seq/${sc}_$seed.log" 2>&1 ||
      echo "eval-stress: ds3d-synth $sc seed $seed failed (see $out/seq/${sc}_$seed.log)" >&2 &
  done
done
wait
# The recorded slice: frames 230-299 of bonn_crowd_first300 as its own sequence (lists cut to
# those frames, images linked), evaluated against the raw groundtruth.txt.
bonn=""
if [[ $quick == 0 && -d "$data/bonn_crowd_first300" ]]; then
  bonn="$out/seq/bonn_crowd_230_299"
  mkdir -p "$bonn"
  "$py" - "$data/bonn_crowd_first300" "$bonn" <<'EOF'
import os, sys
src, dst = sys.argv[1], sys.argv[2]
def entries(name):
    lines = open(os.path.join(src, name)).read().splitlines()
    return [l for l in lines if l.strip() and not l.startswith("#")], [l for l in lines if l.startswith("#")]
rgb, rgb_head = entries("rgb.txt")
rgb = rgb[230:300]
t0, t1 = float(rgb[0].split()[0]), float(rgb[-1].split()[0])
def cut(name, margin):
    e, head = entries(name)
    keep = [l for l in e if t0 - margin <= float(l.split()[0]) <= t1 + margin]
    open(os.path.join(dst, name), "w").write("\n".join(head + keep) + "\n")
open(os.path.join(dst, "rgb.txt"), "w").write("\n".join(rgb_head + rgb) + "\n")
cut("depth.txt", 0.02)
cut("groundtruth.txt", 0.1)
for f in ("camera.txt",):
    open(os.path.join(dst, f), "w").write(open(os.path.join(src, f)).read())
for d in ("rgb", "depth"):
    link = os.path.join(dst, d)
    if not os.path.islink(link):
        os.symlink(os.path.abspath(os.path.join(src, d)), link)
EOF
else
  [[ $quick == 1 ]] || echo "eval-stress: no $data/bonn_crowd_first300 (set DS3D_DATA_DIR); Bonn slice skipped" >&2
fi

# 2. Runs: one line per run "scenario seed mode dir gt".
list="$out/runs/list.txt"
: >"$list"
for sc in $scenarios; do
  for seed in $seeds; do
    d="$out/seq/${sc}_$seed"
    for m in "${modes_real[@]}" "file:detections_noisy.jsonl" "file:detections_noisy.jsonl+geometric"; do
      printf '%s\t%s\t%s\t%s\t%s\n' "$sc" "$seed" "$m" "$d" "$d/groundtruth.txt" >>"$list"
    done
  done
done
if [[ -n "$bonn" ]]; then
  for m in "${modes_real[@]}"; do
    printf '%s\t%s\t%s\t%s\t%s\n' "bonn_crowd_230_299" "-" "$m" "$bonn" "$data/bonn_crowd_first300/groundtruth.txt" >>"$list"
  done
fi

# run_one N SCENARIO SEED MODE DIR GT: writes runs/N.row (CSV fields after the key).
run_one() {
  local n=$1 sc=$2 seed=$3 mode=$4 dir=$5 gt=$6 stem="$out/runs/$1" rc
  local -a args
  read -r -a args <<<"$mode"
  args[0]="${args[0]/file:/file:$dir/}"
  "$slam" "$dir" --dynamic "${args[@]}" --out "$stem.txt" --stats "$stem.json" --quiet \
    >"$stem.log" 2>&1
  rc=$?
  if [[ $rc -ne 0 ]]; then
    echo "crashed (rc $rc),,,,," >"$stem.row"
    echo "eval-stress: CRASH $sc seed $seed mode '$mode' (rc $rc, see $stem.log)" >&2
    return
  fi
  if ! "$evalb" ate "$gt" "$stem.txt" --window 3 --json >"$stem.ate.json" 2>>"$stem.log"; then
    echo "eval failed,,,,," >"$stem.row"
    echo "eval-stress: ds3d-eval failed for $sc seed $seed mode '$mode' (see $stem.log)" >&2
    return
  fi
  "$py" - "$stem.ate.json" "$stem.json" >"$stem.row" <<'EOF'
import json, sys
a, s = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
print(f"ok,{a['rmse']:.4f},{a['worst_window_rmse']:.4f},{s['tracked_frames']},{s['frames']},{s['fps_median']:.1f}")
EOF
}
n=0
while IFS=$'\t' read -r sc seed mode dir gt; do
  throttle
  run_one "$n" "$sc" "$seed" "$mode" "$dir" "$gt" &
  n=$((n + 1))
done <"$list"
wait
t_end=$(date +%s)

# 3. Table and CSV.
"$py" - "$list" "$out" "$frames" "$((t_end - t_start))" <<'EOF'
import os, sys
lst, out, frames, wall = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
rows, crashed = [], 0
for n, line in enumerate(open(lst).read().splitlines()):
    sc, seed, mode = line.split("\t")[:3]
    p = os.path.join(out, "runs", f"{n}.row")
    f = open(p).read().strip().split(",") if os.path.exists(p) else ["missing", "", "", "", "", ""]
    nfr = frames if seed != "-" else "70"
    rows.append(dict(scenario=sc, seed=seed, mode=mode, frames=nfr, status=f[0], ate_rmse=f[1],
                     worst_window_rmse=f[2], tracked=f[3], total=f[4], fps_median=f[5]))
    crashed += f[0] != "ok"
md = ["| scenario | seed | mode | ATE RMSE [m] | worst 3-s window [m] | tracked / frames | fps median |",
      "|---|---|---|---|---|---|---|"]
for r in rows:
    if r["status"] != "ok":
        md.append(f"| {r['scenario']} | {r['seed']} | {r['mode']} | {r['status']} | | | |")
    else:
        md.append(f"| {r['scenario']} | {r['seed']} | {r['mode']} | {r['ate_rmse']} | "
                  f"{r['worst_window_rmse']} | {r['tracked']} / {r['total']} | {r['fps_median']} |")
md.append("")
md.append(f"{len(rows)} runs, {crashed} not completed, wall time {wall // 60} min {wall % 60} s")
text = "\n".join(md) + "\n"
print(text, end="")
open(os.path.join(out, "stress.md"), "w").write(text)
keys = ["scenario", "seed", "mode", "frames", "status", "ate_rmse", "worst_window_rmse", "tracked",
        "total", "fps_median"]
with open(os.path.join(out, "stress.csv"), "w") as f:
    f.write(",".join(keys) + "\n")
    for r in rows:
        f.write(",".join(r[k] for k in keys) + "\n")
EOF
status=0
grep -qv '^ok,' "$out"/runs/*.row 2>/dev/null && status=1
if [[ -n "$check" ]]; then
  compare "$out/stress.csv" "$check" || { c=$?; [[ $status -eq 0 ]] && status=$c; }
fi
exit $status
