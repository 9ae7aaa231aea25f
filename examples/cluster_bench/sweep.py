#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""What this shows: how ds3d.hdbscan scales with the number of points n and the dimension D, next
to the reference ``hdbscan`` library, ``fast_hdbscan`` and scikit-learn's ``HDBSCAN`` when they can
be imported (none is a Debian package; each one that is missing is skipped with a message), and
whether their partitions agree with ds3d's (adjusted Rand index; 1 = the same partition).

Data: 5 Gaussian blobs (sigma 0.5, centres in [-10, 10]^D) plus 10 % uniform noise, seeded, the
same family as BM_HdbscanBlobs in cluster_bench.cpp. Parameters: min_cluster_size=15,
min_samples=10, single thread for ds3d. Time: best of --reps runs, wall clock (time.perf_counter)
or, with --clock cpu, the process's CPU time (time.process_time: robust on a loaded machine, but
it adds up all threads of a multi-threaded library).

Writes OUT/scaling.png (log-log time vs n), OUT/scaling.md (markdown table) and
OUT/scaling.json, prints the table, and exits with 1 when a partition disagrees
(ARI < 0.999) or ds3d finds no cluster in the blobs.

    PYTHONPATH=build/python /usr/bin/python3 examples/cluster_bench/sweep.py --out build/cluster_bench
    ... sweep.py --quick      # n in {500, 2000}, D in {2, 3}, one run each (seconds; make test)
"""
import argparse
import importlib
import json
import os
import platform
import sys
import time

import numpy as np

import ds3d

MIN_CLUSTER_SIZE = 15
MIN_SAMPLES = 10


def blobs(n, dim, seed=42):
    """n points in dim dimensions: 5 blobs + every 10th point uniform noise."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-10.0, 10.0, size=(5, dim))
    x = centres[np.arange(n) % 5] + rng.normal(0.0, 0.5, size=(n, dim))
    noise = np.arange(n) % 10 == 9
    x[noise] = rng.uniform(-10.0, 10.0, size=(int(noise.sum()), dim))
    return x


def adjusted_rand_index(a, b):
    """Hubert & Arabie (1985) adjusted Rand index of two labelings (noise -1 is one more label)."""
    a = np.unique(np.asarray(a), return_inverse=True)[1]
    b = np.unique(np.asarray(b), return_inverse=True)[1]
    table = np.zeros((a.max() + 1, b.max() + 1), dtype=np.int64)
    np.add.at(table, (a, b), 1)

    def pairs(m):
        return (m * (m - 1) // 2).sum()

    index = pairs(table)
    rows, cols, total = pairs(table.sum(1)), pairs(table.sum(0)), len(a) * (len(a) - 1) // 2
    expected = rows * cols / total if total else 0.0
    maximum = 0.5 * (rows + cols)
    return 1.0 if maximum == expected else float((index - expected) / (maximum - expected))


def competitors():
    """(name, fit(x) -> labels) for each reference implementation that can be imported."""
    found = []
    try:
        hdbscan = importlib.import_module("hdbscan")
        found.append(("hdbscan", lambda x: hdbscan.HDBSCAN(
            min_cluster_size=MIN_CLUSTER_SIZE, min_samples=MIN_SAMPLES).fit(x).labels_))
    except ImportError:
        print("sweep: 'hdbscan' is not importable (not a Debian package): skipped")
    try:
        fast = importlib.import_module("fast_hdbscan")
        found.append(("fast_hdbscan", lambda x: fast.HDBSCAN(
            min_cluster_size=MIN_CLUSTER_SIZE, min_samples=MIN_SAMPLES).fit(x).labels_))
    except ImportError:
        print("sweep: 'fast_hdbscan' is not importable (not a Debian package): skipped")
    try:
        from sklearn.cluster import HDBSCAN as SkHdbscan  # scikit-learn >= 1.3
        found.append(("sklearn", lambda x: SkHdbscan(
            min_cluster_size=MIN_CLUSTER_SIZE, min_samples=MIN_SAMPLES).fit(x).labels_))
    except ImportError:
        print("sweep: sklearn.cluster.HDBSCAN is not importable (needs scikit-learn >= 1.3): "
              "skipped")
    return found


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            return next(l.split(":", 1)[1].strip() for l in f if l.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def best_time(fn, x, reps, clock):
    best, out = float("inf"), None
    for _ in range(reps):
        t0 = clock()
        out = fn(x)
        best = min(best, clock() - t0)
    return best, out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="build/cluster_bench", help="output folder")
    ap.add_argument("--quick", action="store_true", help="tiny sweep, one run each (make test)")
    ap.add_argument("--sizes", type=int, nargs="+", help="n values (default 1k .. 100k)")
    ap.add_argument("--dims", type=int, nargs="+", help="D values (default 2 3 5)")
    ap.add_argument("--reps", type=int, default=3, help="runs per case; the best is kept")
    ap.add_argument("--clock", choices=["wall", "cpu"], default="wall",
                    help="wall: time.perf_counter; cpu: time.process_time (all threads)")
    a = ap.parse_args()
    sizes = a.sizes or ([500, 2000] if a.quick else [1000, 3000, 10000, 30000, 100000])
    dims = a.dims or ([2, 3] if a.quick else [2, 3, 5])
    reps = 1 if a.quick else a.reps
    clock = time.perf_counter if a.clock == "wall" else time.process_time
    if any(n < 2 * MIN_CLUSTER_SIZE for n in sizes) or any(d < 1 for d in dims) or reps < 1:
        sys.exit(f"sweep: sizes must be >= {2 * MIN_CLUSTER_SIZE}, dims >= 1, reps >= 1")
    os.makedirs(a.out, exist_ok=True)

    def run_ds3d(x):
        return ds3d.hdbscan(x, min_cluster_size=MIN_CLUSTER_SIZE, min_samples=MIN_SAMPLES,
                            num_threads=1).labels

    load_start = os.getloadavg()[0]
    others = competitors()
    names = ["ds3d"] + [name for name, _ in others]
    rows, ok = [], True
    for dim in dims:
        for n in sizes:
            x = blobs(n, dim)
            t, labels = best_time(run_ds3d, x, reps, clock)
            row = {"n": n, "D": dim, "seconds": {"ds3d": t}, "ari": {},
                   "clusters": int(labels.max()) + 1, "noise": int((labels < 0).sum())}
            if row["clusters"] < 1:
                print(f"sweep: ds3d found no cluster for n={n} D={dim}", file=sys.stderr)
                ok = False
            for name, fit in others:
                t_other, other = best_time(fit, x, reps, clock)
                row["seconds"][name] = t_other
                row["ari"][name] = adjusted_rand_index(labels, other)
                if row["ari"][name] < 0.999:
                    print(f"sweep: {name} disagrees with ds3d for n={n} D={dim}: "
                          f"ARI {row['ari'][name]:.4f}", file=sys.stderr)
                    ok = False
            rows.append(row)
            print(f"  n={n:>7} D={dim}: " + ", ".join(
                f"{k} {v * 1e3:.1f} ms" for k, v in row["seconds"].items()), flush=True)

    machine = f"{cpu_model()}, {os.cpu_count()} CPUs, load average {load_start:.1f} -> " \
              f"{os.getloadavg()[0]:.1f}"
    header = "| n | D | clusters | noise | " + " | ".join(f"{k} [ms]" for k in names) + \
        "".join(f" | ARI vs {k}" for k in names[1:]) + " |"
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    for r in rows:
        cells = [str(r["n"]), str(r["D"]), str(r["clusters"]), str(r["noise"])]
        cells += [f"{r['seconds'][k] * 1e3:.1f}" for k in names]
        cells += [f"{r['ari'][k]:.4f}" for k in names[1:]]
        lines.append("| " + " | ".join(cells) + " |")
    table = "\n".join(lines)
    with open(os.path.join(a.out, "scaling.md"), "w") as f:
        f.write(f"ds3d {ds3d.__version__}, min_cluster_size={MIN_CLUSTER_SIZE}, "
                f"min_samples={MIN_SAMPLES}, best of {reps} ({a.clock} time); {machine}\n\n"
                f"{table}\n")
    with open(os.path.join(a.out, "scaling.json"), "w") as f:
        json.dump({"machine": machine, "reps": reps, "clock": a.clock, "rows": rows}, f,
                  indent=1)
    print(table)

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=100)
    markers, styles = "osd^v", ["-", "--", ":", "-."]
    for di, dim in enumerate(dims):
        for li, name in enumerate(names):
            pts = [(r["n"], r["seconds"][name]) for r in rows if r["D"] == dim]
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], styles[li % 4],
                      marker=markers[di % 5], color=f"C{li}", label=f"{name}, D={dim}")
    ns = np.array(sorted(sizes), dtype=float)
    t0 = min(r["seconds"]["ds3d"] for r in rows if r["n"] == ns[0])
    ax.loglog(ns, t0 * ns / ns[0], color="0.6", linewidth=0.8, label="∝ n (guide)")
    ax.set_xlabel("points n")
    ax.set_ylabel(f"{a.clock} time [s] (best of {reps})")
    ax.set_title("HDBSCAN scaling (5 blobs + 10 % noise, mcs=15, ms=10)", fontsize=10)
    ax.grid(True, which="both", linewidth=0.3)
    ax.legend(fontsize=7)
    fig.text(0.01, 0.01, machine, fontsize=6, color="0.4")
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "scaling.png"))
    print(f"sweep: wrote {a.out}/scaling.png, scaling.md, scaling.json")
    if not ok:
        sys.exit(1)


if __name__ == "__main__":
    main()
