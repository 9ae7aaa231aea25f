# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""What runs on a worker: preparing one sequence (ds3d-synth, or a frame slice of a recorded one)
and one cell (ds3d-slam, then ds3d-eval ate / rpe). Plain dicts in and out, so the same functions
run in a local process pool and on Dask workers; errors become a status, never an exception."""
import json
import os
import shlex
import shutil
import subprocess
import time
import traceback

MARKER = "result.json"   # a finished cell: its row, and the commands that made it
FAILED = "failed.json"   # a cell that did not finish (run again next time)
SEQ_MARKER = ".ds3d-bench-seq.json"

ROW_KEYS = ["sequence", "config", "seed", "status", "ate_rmse", "rpe_trans_rmse", "rpe_rot_rmse_deg",
            "worst_window_rmse", "tracked_frames", "frames", "fps_median", "p95_interval_ms",
            "dynamic_fraction", "log", "dir"]


def tool(path):
    """An executable: the given path when it exists here, else the same name on PATH."""
    if os.access(path, os.X_OK):
        return path
    found = shutil.which(os.path.basename(path))
    if not found:
        raise FileNotFoundError(f"ds3d-bench: tool '{path}' not found on this machine "
                                f"(build it, install ds3d, or set DS3D_BIN_DIR)")
    return found


def _write_json(path, obj):
    tmp = f"{path}.tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(obj, f, indent=1, sort_keys=True)
        f.write("\n")
    os.replace(tmp, path)


def _read_json(path):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def slice_sequence(src, dst, first, stop):
    """A TUM-layout sequence of frames [first, stop) of src in dst: rgb.txt cut to those frames,
    depth.txt (±0.02 s) and groundtruth.txt (±0.1 s) to their time span, camera.txt copied,
    rgb/ and depth/ linked (the logic of scripts/eval-stress.sh)."""
    def entries(name):
        with open(os.path.join(src, name), encoding="utf-8") as f:
            lines = f.read().splitlines()
        return ([ln for ln in lines if ln.strip() and not ln.startswith("#")],
                [ln for ln in lines if ln.startswith("#")])

    def write(name, lines):
        with open(os.path.join(dst, name), "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")

    os.makedirs(dst, exist_ok=True)
    rgb, rgb_head = entries("rgb.txt")
    rgb = rgb[first:stop]
    if not rgb:
        raise ValueError(f"ds3d-bench: frames [{first}, {stop}) of '{src}' are empty")
    t0, t1 = float(rgb[0].split()[0]), float(rgb[-1].split()[0])
    write("rgb.txt", rgb_head + rgb)
    for name, margin in (("depth.txt", 0.02), ("groundtruth.txt", 0.1)):
        if os.path.exists(os.path.join(src, name)):
            e, head = entries(name)
            write(name, head + [ln for ln in e if t0 - margin <= float(ln.split()[0]) <= t1 + margin])
    if os.path.exists(os.path.join(src, "camera.txt")):
        shutil.copyfile(os.path.join(src, "camera.txt"), os.path.join(dst, "camera.txt"))
    for d in ("rgb", "depth"):
        link = os.path.join(dst, d)
        if not os.path.islink(link) and os.path.isdir(os.path.join(src, d)):
            os.symlink(os.path.abspath(os.path.join(src, d)), link)


def prepare_sequence(task):
    """Generates (ds3d-synth) or slices one sequence into task['dir'] unless its marker records
    the same recipe. Returns {'dir', 'status' ('ok', 'cached' or an error), 'log'}."""
    d, recipe = task["dir"], task["recipe"]
    log = d.rstrip("/") + ".log"
    done = _read_json(os.path.join(d, SEQ_MARKER))
    if done is not None and done.get("recipe") == recipe:
        return {"dir": d, "status": "cached", "log": log}
    try:
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(os.path.dirname(d), exist_ok=True)
        if recipe["kind"] == "synth":
            cmd = [tool(task["synth"]), d] + recipe["args"]
            with open(log, "w", encoding="utf-8") as f:
                f.write(shlex.join(cmd) + "\n")
                f.flush()
                rc = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, check=False).returncode
            if rc != 0:
                return {"dir": d, "status": f"ds3d-synth failed (rc {rc})", "log": log}
        else:
            with open(log, "w", encoding="utf-8") as f:
                f.write(f"frames [{recipe['first']}, {recipe['stop']}) of {recipe['source']}\n")
            slice_sequence(recipe["source"], d, recipe["first"], recipe["stop"])
        _write_json(os.path.join(d, SEQ_MARKER), {"recipe": recipe})
        return {"dir": d, "status": "ok", "log": log}
    except Exception:  # noqa: BLE001  (reported, the others go on)
        with open(log, "a", encoding="utf-8") as f:
            f.write(traceback.format_exc())
        return {"dir": d, "status": "preparation failed", "log": log}


def commands(cell):
    """The exact command lines of a cell: ds3d-slam, ds3d-eval ate, ds3d-eval rpe (lists)."""
    d, ev = cell["dir"], cell["eval"]
    traj = os.path.join(d, "trajectory.txt")
    slam = [cell["tools"]["slam"], cell["seq_dir"]] + cell["slam_args"] + [
        "--out", traj, "--stats", os.path.join(d, "stats.json"), "--quiet"]
    ate = [cell["tools"]["eval"], "ate", cell["groundtruth"], traj, "--window", f"{ev['window']:g}", "--json"]
    if ev["plot"]:
        ate += ["--plot", os.path.join(d, "trajectory.png")]
    rpe = [cell["tools"]["eval"], "rpe", cell["groundtruth"], traj, "--delta", f"{ev['rpe_delta']:g}",
           "--delta-unit", ev["rpe_unit"], "--json"]
    return [slam, ate, rpe]


def cached_result(cell):
    """The stored row of a finished cell made by the same commands, else None."""
    done = _read_json(os.path.join(cell["dir"], MARKER))
    if done and done.get("status") == "ok" and done.get("cmd") == [shlex.join(c) for c in commands(cell)]:
        return done
    return None


def _row(cell, status, log):
    row = {k: None for k in ROW_KEYS}
    row.update(sequence=cell["sequence"], config=cell["config"],
               seed="-" if cell["seed"] is None else cell["seed"], status=status, log=log,
               dir=cell["dir"], cmd=[shlex.join(c) for c in commands(cell)])
    return row


def _metrics(row, ate, rpe, stats):
    row["ate_rmse"] = ate["rmse"]
    row["worst_window_rmse"] = ate.get("worst_window_rmse")
    if rpe:
        row["rpe_trans_rmse"] = rpe["translational"]["rmse"]
        row["rpe_rot_rmse_deg"] = rpe["rotational"]["rmse"]
    row["tracked_frames"] = stats.get("tracked_frames")
    row["frames"] = stats.get("frames")
    row["fps_median"] = stats.get("fps_median")
    row["p95_interval_ms"] = (stats.get("frame_interval") or {}).get("p95_ms")
    row["dynamic_fraction"] = (stats.get("totals") or {}).get("dynamic_fraction")


def _run(cmd, stdout_path, log, mode="a"):
    with open(log, mode, encoding="utf-8") as lf:
        lf.write(f"$ {shlex.join(cmd)}\n")
        lf.flush()
        if stdout_path is None:
            return subprocess.run(cmd, stdout=lf, stderr=subprocess.STDOUT, check=False).returncode
        with open(stdout_path, "w", encoding="utf-8") as out:
            return subprocess.run(cmd, stdout=out, stderr=lf, check=False).returncode


def run_cell(cell):
    """Runs one cell into cell['dir'] (trajectory.txt, stats.json, ate.json, rpe.json,
    trajectory.png, cmd.txt, log.txt) and returns its row; a finished cell leaves result.json."""
    d = cell["dir"]
    log = os.path.join(d, "log.txt")
    try:
        os.makedirs(d, exist_ok=True)
        for name in (MARKER, FAILED):
            if os.path.exists(os.path.join(d, name)):
                os.remove(os.path.join(d, name))
        cell = dict(cell, tools={k: tool(v) for k, v in cell["tools"].items()})
        slam, ate, rpe = commands(cell)
        with open(os.path.join(d, "cmd.txt"), "w", encoding="utf-8") as f:
            f.write("\n".join(shlex.join(c) for c in (slam, ate, rpe)) + "\n")
        t0 = time.time()
        rc = _run(slam, None, log, "w")
        if rc != 0:
            row = _row(cell, f"crashed (rc {rc})", log)
        elif _run(ate, os.path.join(d, "ate.json"), log) != 0:
            row = _row(cell, "eval failed", log)
        else:
            rpe_ok = _run(rpe, os.path.join(d, "rpe.json"), log) == 0  # too short: RPE left empty
            row = _row(cell, "ok", log)
            _metrics(row, _read_json(os.path.join(d, "ate.json")),
                     _read_json(os.path.join(d, "rpe.json")) if rpe_ok else None,
                     _read_json(os.path.join(d, "stats.json")) or {})
        row["wall_s"] = round(time.time() - t0, 3)
    except Exception:  # noqa: BLE001  (reported, the others go on)
        os.makedirs(d, exist_ok=True)
        with open(log, "a", encoding="utf-8") as f:
            f.write(traceback.format_exc())
        row = _row(cell, "error", log)
    _write_json(os.path.join(d, MARKER if row["status"] == "ok" else FAILED), row)
    return row
