#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Runs every Google Benchmark binary in BUILD/bin (*_bench), writes bench/results/<name>.json
and a markdown summary bench/results/summary.md (median of the repetitions, with the machine).

Usage: run_bench.py [--build-dir build] [--out bench/results] [--filter REGEX] [--repetitions N]
"""
import argparse
import json
import pathlib
import platform
import subprocess
import sys


def fmt_time(ns):
    for unit, scale in (("s", 1e9), ("ms", 1e6), ("us", 1e3)):
        if ns >= scale:
            return f"{ns / scale:.3g} {unit}"
    return f"{ns:.3g} ns"


def cpu_model():
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "cpu"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--build-dir", default="build")
    ap.add_argument("--out", default="bench/results")
    ap.add_argument("--filter", default="")
    ap.add_argument("--repetitions", type=int, default=5)
    ap.add_argument("--only", nargs="*", help="bench binary names (default: all)")
    args = ap.parse_args()

    bindir = pathlib.Path(args.build_dir) / "bin"
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    benches = sorted(p for p in bindir.glob("*_bench") if p.is_file())
    if args.only:
        benches = [b for b in benches if b.name in args.only]
    if not benches:
        print(f"run_bench: no *_bench binaries in {bindir}", file=sys.stderr)
        return 1
    lines = ["# ds3d benchmark summary", "",
             f"Machine: {platform.node()} ({platform.machine()}, {cpu_model()}),"
             f" Python {platform.python_version()}", ""]
    for b in benches:
        path = out / f"{b.name}.json"
        cmd = [str(b), f"--benchmark_out={path}", "--benchmark_out_format=json",
               f"--benchmark_repetitions={args.repetitions}",
               "--benchmark_report_aggregates_only=true"]
        if args.filter:
            cmd.append(f"--benchmark_filter={args.filter}")
        print("run_bench:", " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        data = json.loads(path.read_text())
        lines += [f"## {b.name}", "", f"`{' '.join(cmd)}`", "",
                  "| benchmark | median time | CPU time | items/s |", "|---|---|---|---|"]
        for r in data.get("benchmarks", []):
            if r.get("aggregate_name") not in (None, "median"):
                continue
            scale = {"ns": 1, "us": 1e3, "ms": 1e6, "s": 1e9}[r.get("time_unit", "ns")]
            ips = r.get("items_per_second")
            lines.append(f"| {r['run_name']} | {fmt_time(r['real_time'] * scale)} | "
                         f"{fmt_time(r['cpu_time'] * scale)} | "
                         f"{'' if ips is None else f'{ips:.3g}'} |")
        ctx = data.get("context", {})
        lines += ["", f"{ctx.get('num_cpus', '?')} CPUs at {ctx.get('mhz_per_cpu', '?')} MHz, "
                  f"load average {ctx.get('load_avg', '?')}", ""]
    (out / "summary.md").write_text("\n".join(lines) + "\n")
    print(f"run_bench: wrote {out}/summary.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
