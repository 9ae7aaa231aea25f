# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d-bench: sequences x configurations x seeds of a suite file through ds3d-slam and ds3d-eval,
locally or on a Dask cluster, into one results folder (docs/bench.md)."""
import argparse
import os
import pathlib
import shlex
import sys
import time

from . import cell as cellmod
from .executor import DaskRunner, ExecutorError, run_local
from .report import plot_ate, write_tables
from .suite import SuiteError, cell_id, load_suite, sequence_dir_name

TOOLS = {"slam": ("DS3D_SLAM", "ds3d-slam"), "eval": ("DS3D_EVAL", "ds3d-eval"),
         "synth": ("DS3D_SYNTH", "ds3d-synth")}


def find_tools(bin_dir=None):
    """Absolute paths of ds3d-slam, ds3d-eval and ds3d-synth: --bin-dir, else $DS3D_SLAM / ... one
    by one or $DS3D_BIN_DIR, else the build tree next to this package (build/bin), else PATH."""
    import shutil

    here = pathlib.Path(__file__).resolve().parents[3] / "bin"  # build/python/ds3d/bench -> build/bin
    out = {}
    for key, (env, name) in TOOLS.items():
        if bin_dir:
            path = os.path.join(bin_dir, name)
        elif os.environ.get(env):
            path = os.environ[env]
        elif os.environ.get("DS3D_BIN_DIR"):
            path = os.path.join(os.environ["DS3D_BIN_DIR"], name)
        elif (here / name).is_file():
            path = str(here / name)
        else:
            path = shutil.which(name) or name
        out[key] = os.path.abspath(path) if os.sep in path else path
    return out


def _dynamic_arg(spec, seq_dir):
    # file:REL is relative to the sequence folder (e.g. the detections_noisy.jsonl of ds3d-synth)
    parts = []
    for p in spec.split("+"):
        if p.startswith("file:") and not os.path.isabs(p[5:]):
            p = "file:" + os.path.join(seq_dir, p[5:])
        parts.append(p)
    return "+".join(parts)


def slam_args(seq, conf, seq_dir):
    args = []
    if seq.get("camera"):
        args += ["--camera", seq["camera"]]
    if conf.get("config"):
        args += ["--config", conf["config"]]
    if conf.get("dynamic"):
        args += ["--dynamic", _dynamic_arg(conf["dynamic"], seq_dir)]
    if conf.get("gate"):
        args += ["--gate", conf["gate"]]
    if conf.get("weights"):
        args += ["--weights", conf["weights"]]
    for s in conf["_set"]:
        args += ["--set", s]
    mf = conf.get("max_frames") or seq.get("max_frames")
    if mf:
        args += ["--max-frames", str(mf)]
    return args + conf["args"]


def plan(suite, out, tools):
    """(preparation tasks, cells) of a suite: one task per synthetic / sliced sequence, one cell
    per sequence x seed x configuration, in table order."""
    preps, cells = [], []
    for seq in suite["sequences"]:
        for seed in seq["seeds"]:
            seq_dir, gt = seq.get("source"), seq.get("groundtruth")
            if seq["kind"] == "synth":
                seq_dir = os.path.join(out, "seq", sequence_dir_name(seq, seed))
                gt = os.path.join(seq_dir, "groundtruth.txt")
                recipe = {"kind": "synth", "args": seq["synth_args"] + ["--seed", str(seed)]}
                preps.append({"dir": seq_dir, "recipe": recipe, "synth": tools["synth"]})
            elif "frames" in seq:
                seq_dir = os.path.join(out, "seq", sequence_dir_name(seq, seed))
                recipe = {"kind": "slice", "source": seq["source"], "first": seq["frames"][0],
                          "stop": seq["frames"][1]}
                preps.append({"dir": seq_dir, "recipe": recipe})
            for conf in suite["configs"]:
                if conf["name"] in seq["skip_configs"]:
                    continue
                cells.append({"id": cell_id(seq, conf, seed), "sequence": seq["name"], "config": conf["name"],
                              "seed": seed, "seq_dir": seq_dir, "groundtruth": gt,
                              "slam_args": slam_args(seq, conf, seq_dir),
                              "tools": {"slam": tools["slam"], "eval": tools["eval"]},
                              "eval": suite["eval"],
                              "dir": os.path.join(out, "cells", cell_id(seq, conf, seed))})
    return preps, cells


def _version():
    from .. import __version__
    return __version__


def parse_args(argv):
    p = argparse.ArgumentParser(prog="ds3d-bench", description=__doc__)
    p.add_argument("suite", help="suite file (.yaml, .yml or .json; docs/bench.md)")
    p.add_argument("--version", action="version", version=f"ds3d-bench {_version()}")
    p.add_argument("--out", help="results folder (default: the suite's out:, else build/bench/<suite name>)")
    p.add_argument("--jobs", type=int, default=0,
                   help="local worker processes (default: cores / threads_per_run of the suite)")
    p.add_argument("--scheduler", help="run on a Dask cluster: tcp://HOST:PORT of its scheduler")
    p.add_argument("--bin-dir", help="folder of ds3d-slam, ds3d-eval, ds3d-synth (default: build tree or PATH)")
    p.add_argument("--force", action="store_true", help="re-run finished cells too")
    p.add_argument("--dry-run", action="store_true", help="print the cells and their ds3d-slam commands")
    p.add_argument("--quiet", action="store_true", help="no per-cell progress lines")
    a = p.parse_args(argv)
    if a.jobs < 0:
        p.error(f"--jobs must be >= 1 (got {a.jobs})")
    if a.scheduler and a.jobs:
        p.error("--jobs and --scheduler exclusive: the cluster's workers set the parallelism")
    return a


def _runner(a, suite):
    if a.scheduler:
        dask = DaskRunner(a.scheduler)
        return (lambda fn, items: dask.run(fn, items)), dask
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    jobs = a.jobs or max(1, cores // suite["threads_per_run"])
    return (lambda fn, items: run_local(fn, items, jobs)), None


def _prepare(run, preps, log):
    """Runs the preparation tasks; returns the set of sequence folders that could not be made."""
    bad = {}
    for i, res in run(cellmod.prepare_sequence, preps):
        status = res.get("status", res.get("__error__"))
        if status not in ("ok", "cached"):
            bad[preps[i]["dir"]] = res.get("log", "")
            log(f"ds3d-bench: sequence {preps[i]['dir']}: {status} (see {res.get('log')})")
    return bad


def _run_cells(run, cells, bad_seqs, force, log):
    rows, todo, reused = [None] * len(cells), [], 0
    for i, c in enumerate(cells):
        if c["seq_dir"] in bad_seqs:
            rows[i] = dict(cellmod._row(c, "sequence failed", bad_seqs[c["seq_dir"]]))
            continue
        done = None if force else cellmod.cached_result(c)
        if done is not None:
            rows[i], reused = done, reused + 1
        else:
            todo.append(i)
    log(f"ds3d-bench: {len(cells)} cells, {reused} finished earlier, {len(todo)} to run")
    for n, (j, res) in enumerate(run(cellmod.run_cell, [cells[i] for i in todo]), 1):
        i = todo[j]
        if "__error__" in res:
            res = dict(cellmod._row(cells[i], "error", res["__error__"]))
        rows[i] = res
        extra = f"ATE {res['ate_rmse']:.4f} m" if res["status"] == "ok" else f"see {res['log']}"
        log(f"[{n}/{len(todo)}] {cells[i]['id']}: {res['status']}, {extra}")
    return rows, reused


def run_suite(a, log):
    suite = load_suite(a.suite)
    for w in suite["warnings"]:
        log(f"ds3d-bench: {w}")
    out = os.path.abspath(a.out or suite["out"] or os.path.join("build", "bench", suite["name"]))
    preps, cells = plan(suite, out, find_tools(a.bin_dir))
    if a.dry_run:
        for c in cells:
            print(f"{c['id']}: {shlex.join(cellmod.commands(c)[0])}")
        return 0
    if not cells:
        log("ds3d-bench: no cell to run (no sequence found)")
        return 1
    os.makedirs(out, exist_ok=True)
    t0 = time.time()
    run, dask = _runner(a, suite)
    try:
        bad = _prepare(run, preps, log)
        rows, reused = _run_cells(run, cells, bad, a.force, log)
    finally:
        if dask is not None:
            dask.close()
    wall = int(time.time() - t0)
    failed = sum(r["status"] != "ok" for r in rows)
    summary = (f"{len(rows)} cells, {failed} not completed, {reused} reused from an earlier run, "
               f"wall time {wall // 60} min {wall % 60} s")
    write_tables(out, rows, summary)
    plot_ate(rows, os.path.join(out, "ate.png"), f"{suite['name']}: ATE RMSE per sequence and configuration")
    log(f"ds3d-bench: {summary}; results in {out}/results.md")
    return 1 if failed else 0


def main(argv=None):
    """Entry point of ds3d-bench and python3 -m ds3d.bench; returns the exit status (0: every
    cell finished, 1: some did not, 2: bad suite or arguments)."""
    a = parse_args(sys.argv[1:] if argv is None else argv)
    log = (lambda m: None) if a.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    try:
        return run_suite(a, log)
    except (SuiteError, ExecutorError) as e:
        print(e, file=sys.stderr)
        return 2
