#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Real-time benchmark of ds3d-slam: every --dynamic mode on the recorded slices, REPS runs each,
one at a time and round-robin (so that a busy minute of the host spreads over all modes), with
detection on every frame. Prints, per mode and sequence, the medians over the runs of fps_median
and of the p95 frame interval (with their ranges), the stage medians (wall / thread CPU), the
latency from frame in to pose out, the ATE and whether the runs gave byte-identical
trajectories. With --check it exits 1 when a mode misses --min-fps or --max-p95-ms.

By default ds3d-slam reads each recording as fast as the pipeline takes it (throughput; the
latency is then mostly the frames waiting in the queues). With --realtime it hands the frames
over at the rate of their timestamps, as a live camera delivers them: the table then adds how
late the input was handed over (input lag p95), the latency is that of a live camera, and
--check skips the fps target (the rate is the camera's) but keeps the p95 interval.

Run it on an otherwise idle machine: the rates are those of the host (docs/benchmarks.md).

  /usr/bin/python3 scripts/eval-realtime.py [--build build] [--reps 3] [--check] [--realtime]
  /usr/bin/python3 scripts/eval-realtime.py --modes none geometric --sequences DIR [DIR ...]

The modes are the configurations of a ds3d.bench suite file (default bench/suites/recorded.yaml,
the README's table), or --modes: each one --dynamic spec plus its flags. ds3d is imported from
BUILD/python.

Sequences are folder names under $DS3D_DATA_DIR (default ../shared/data next to the
repository) or paths; without the data it prints SKIPPED and exits 0.
"""
import argparse
import json
import os
import pathlib
import shlex
import statistics
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
SUITE = ROOT / "bench" / "suites" / "recorded.yaml"
SEQUENCES = ["bonn_crowd_first300", "tum_fr1_xyz_first400"]
STAGES = ["extract", "detect", "prepare", "filter", "track"]


def parse_args(argv):
    p = argparse.ArgumentParser(prog="eval-realtime", description=__doc__.split("\n\n")[0])
    p.add_argument("--build", default=str(ROOT / "build"), help="build folder with bin/ds3d-slam")
    p.add_argument("--data", default=os.environ.get("DS3D_DATA_DIR", str(ROOT.parent / "shared" / "data")))
    p.add_argument("--sequences", nargs="+", default=SEQUENCES)
    p.add_argument("--suite", default=str(SUITE), help="ds3d.bench suite whose configs are the modes")
    p.add_argument("--modes", nargs="+", default=None,
                   help="instead of the suite's configs: each one --dynamic spec plus its flags")
    p.add_argument("--reps", type=int, default=3, help="runs per mode and sequence, >= 1")
    p.add_argument("--out", default=None, help="results folder (default BUILD/eval-realtime)")
    p.add_argument("--check", action="store_true", help="exit 1 when a mode misses the targets")
    p.add_argument("--realtime", action="store_true",
                   help="play the recordings at their recorded rate (ds3d-slam --realtime)")
    p.add_argument("--min-fps", type=float, default=30.0, help="target fps median, > 0")
    p.add_argument("--max-p95-ms", type=float, default=50.0, help="target p95 frame interval [ms], > 0")
    a = p.parse_args(argv)
    if a.reps < 1:
        p.error(f"--reps must be >= 1, got {a.reps}")
    for name in ("min_fps", "max_p95_ms"):
        if not getattr(a, name) > 0:
            p.error(f"--{name.replace('_', '-')} must be > 0, got {getattr(a, name)}")
    return a


def sequence_dirs(args):
    dirs = []
    for s in args.sequences:
        d = pathlib.Path(s) if os.sep in s else pathlib.Path(args.data) / s
        if (d / "rgb.txt").is_file():
            dirs.append(d)
        else:
            print(f"eval-realtime: SKIPPED {s} (no {d / 'rgb.txt'})")
    return dirs


def suite_modes(build, suite):
    """(name, ds3d-slam flags) of every configuration of a ds3d.bench suite file."""
    sys.path.insert(0, str(build / "python"))
    from ds3d.bench.cli import slam_args
    from ds3d.bench.suite import load_suite
    try:
        configs = load_suite(suite)["configs"]
    except (OSError, ValueError) as e:  # SuiteError is a ValueError
        print(f"eval-realtime: --suite {suite}: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    return [(c["name"], slam_args({}, c, "")) for c in configs]


def run_one(slam, seq, flags, stem):
    cmd = [str(slam), str(seq), *flags, "--out", f"{stem}.txt", "--stats", f"{stem}.json", "--quiet"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"eval-realtime: '{shlex.join(cmd)}' failed ({done.returncode}):\n"
                           f"{done.stderr.strip()}")
    return json.loads(pathlib.Path(f"{stem}.json").read_text())


def ate(eval_bin, seq, traj):
    """The ATE RMSE [m], or None (with the command and its stderr on stderr) when ds3d-eval fails,
    e.g. for a sequence without groundtruth.txt."""
    cmd = [str(eval_bin), "ate", str(seq / "groundtruth.txt"), traj, "--json"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode == 0:
        return json.loads(done.stdout)["rmse"]
    print(f"eval-realtime: no ATE for {seq.name}: '{shlex.join(cmd)}' failed ({done.returncode}): "
          f"{done.stderr.strip()}", file=sys.stderr)
    return None


def median_of(stats, get):
    values = [v for v in (get(s) for s in stats) if v is not None]
    return statistics.median(values) if values else None


def stage(stats, key, name):
    return median_of(stats, lambda s: s.get(key, {}).get(name, {}).get("median_ms"))


def summarise(seq, mode, stats, stems, eval_bin):
    fps = [s["fps_median"] for s in stats]
    p95 = [s["frame_interval"]["p95_ms"] for s in stats]
    trajs = [pathlib.Path(f"{st}.txt").read_bytes() for st in stems]
    return {
        "sequence": seq.name, "mode": mode, "runs": len(stats),
        "fps_median": statistics.median(fps), "fps_range": [min(fps), max(fps)],
        "p95_ms": statistics.median(p95), "p95_range": [min(p95), max(p95)],
        "stages_wall_ms": {n: stage(stats, "stages", n) for n in STAGES},
        "stages_cpu_ms": {n: stage(stats, "stages_cpu", n) for n in STAGES},
        "latency_ms": [median_of(stats, lambda s: s["latency"]["median_ms"]),
                       median_of(stats, lambda s: s["latency"]["p95_ms"])],
        "realtime": bool(stats[0].get("realtime")),
        "input_lag_p95_ms": median_of(stats, lambda s: (s.get("input_lag") or {}).get("p95_ms")),
        "tracked": f"{stats[0]['tracked_frames']}/{stats[0]['frames']}",
        "ate_rmse": ate(eval_bin, seq, f"{stems[0]}.txt"),
        "identical": all(t == trajs[0] for t in trajs),
    }


def fmt(v, digits=1):
    return "–" if v is None else f"{v:.{digits}f}"


def table(rows):
    live = any(r["realtime"] for r in rows)
    head = ("| sequence | `--dynamic` | fps median (range) | p95 interval [ms] (range) | "
            + " | ".join(f"{n} wall / CPU [ms]" for n in STAGES)
            + " | latency median / p95 [ms] | " + ("input lag p95 [ms] | " if live else "")
            + "ATE [m] | tracked | identical runs |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        st = " | ".join(f"{fmt(r['stages_wall_ms'][n])} / {fmt(r['stages_cpu_ms'][n])}" for n in STAGES)
        lines.append(
            f"| {r['sequence']} | `{r['mode']}` | {r['fps_median']:.1f} ({r['fps_range'][0]:.1f}–"
            f"{r['fps_range'][1]:.1f}) | {r['p95_ms']:.1f} ({r['p95_range'][0]:.1f}–"
            f"{r['p95_range'][1]:.1f}) | {st} | {fmt(r['latency_ms'][0], 0)} / "
            f"{fmt(r['latency_ms'][1], 0)} | "
            + (f"{fmt(r['input_lag_p95_ms'])} | " if live else "")
            + f"{fmt(r['ate_rmse'], 4)} | {r['tracked']} | "
            f"{'yes' if r['identical'] else 'NO'} |")
    return "\n".join(lines)


def misses(rows, args):
    """The rows that miss a target, said with both figures. --realtime: the rate is the camera's,
    so only the p95 interval is checked."""
    def missed(r):
        slow = not args.realtime and r["fps_median"] < args.min_fps
        return slow or r["p95_ms"] > args.max_p95_ms
    return [f"{r['sequence']} `{r['mode']}`: fps median {r['fps_median']:.1f} (target >= "
            f"{args.min_fps:g}{', not checked with --realtime' if args.realtime else ''}), "
            f"p95 interval {r['p95_ms']:.1f} ms (target <= {args.max_p95_ms:g})"
            for r in rows if missed(r)]


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    build = pathlib.Path(args.build)
    slam, eval_bin = build / "bin" / "ds3d-slam", build / "bin" / "ds3d-eval"
    for b in (slam, eval_bin):
        if not os.access(b, os.X_OK):
            print(f"eval-realtime: {b} not built (cmake --build {build} --target ds3d-slam ds3d-eval)",
                  file=sys.stderr)
            return 2
    seqs = sequence_dirs(args)
    if not seqs:
        return 0
    modes = ([(m, ["--dynamic", *shlex.split(m)]) for m in args.modes] if args.modes
             else suite_modes(build, args.suite))
    out = pathlib.Path(args.out or build / "eval-realtime")
    out.mkdir(parents=True, exist_ok=True)
    runs = {}
    for rep in range(1, args.reps + 1):
        for seq in seqs:
            for i, (_, flags) in enumerate(modes):
                stem = str(out / f"{seq.name}_{i}_{rep}")
                flags_run = [*flags, "--realtime"] if args.realtime else flags
                runs.setdefault((seq, i), []).append((run_one(slam, seq, flags_run, stem), stem))
    rows = [summarise(seq, modes[i][0], [s for s, _ in v], [st for _, st in v], eval_bin)
            for (seq, i), v in runs.items()]
    (out / "results.json").write_text(json.dumps(rows, indent=1))
    print(table(rows))
    print(f"\nresults: {out / 'results.json'}")
    missed = misses(rows, args)
    for m in missed:
        print(f"eval-realtime: target missed: {m}")
    return 1 if args.check and missed else 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except RuntimeError as e:  # a run that failed: its command and stderr; earlier runs stay in --out
        print(e, file=sys.stderr)
        sys.exit(1)
