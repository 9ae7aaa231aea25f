# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d-bench (python/ds3d/bench): a tiny synthetic suite run locally and on a 2-worker Dask
LocalCluster gives the same trajectories and table values; finished cells are not re-run; a
crashing cell is reported with its log and does not stop the others; bad suites are refused."""
import json
import os
import pathlib
import subprocess
import sys

import pytest

bench = pytest.importorskip("ds3d.bench")
from ds3d.bench import cli, load_suite, SuiteError  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = pathlib.Path(os.environ.get("DS3D_BUILD_DIR", ROOT / "build")) / "bin"
if not all((BIN / t).is_file() for t in ("ds3d-slam", "ds3d-eval", "ds3d-synth")):
    pytest.skip(f"ds3d-slam / ds3d-eval / ds3d-synth not built in {BIN}", allow_module_level=True)

# Columns that depend on the clock or on the results folder, not on the computation.
NOT_COMPARED = {"fps_median", "p95_interval_ms", "wall_s", "dir", "log", "cmd"}


def _suite(path, configs):
    path.write_text(json.dumps({
        "name": "tiny", "seeds": [1],
        "sequences": [{"synth": {"scenario": "walking_xyz", "frames": 8}, "name": "wx"}],
        "configs": configs, "eval": {"rpe_delta": 1, "rpe_unit": "f"}, "threads_per_run": 1}))
    return path


def _run(suite, out, *extra):
    return cli.main([str(suite), "--out", str(out), "--bin-dir", str(BIN), "--quiet", *extra])


def _rows(out):
    return json.loads((out / "results.json").read_text())["rows"]


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    d = tmp_path_factory.mktemp("bench")
    suite = _suite(d / "tiny.json", ["none", {"dynamic": "geometric"}])
    assert _run(suite, d / "local", "--jobs", "2") == 0
    return {"suite": suite, "out": d / "local", "rows": _rows(d / "local"), "tmp": d}


def test_local_run_writes_table_plots_and_cells(local):
    out, rows = local["out"], local["rows"]
    assert [(r["sequence"], r["seed"], r["config"], r["status"]) for r in rows] == [
        ("wx", 1, "none", "ok"), ("wx", 1, "geometric", "ok")]
    for r in rows:
        assert 0 < r["ate_rmse"] < 0.1 and 0 < r["worst_window_rmse"] < 0.1 and r["rpe_trans_rmse"] > 0
        assert r["tracked_frames"] == r["frames"] == 8 and r["fps_median"] > 0
        assert r["p95_interval_ms"] > 0
        assert (r["dynamic_fraction"] == 0) == (r["config"] == "none") and r["dynamic_fraction"] < 1
        cell = pathlib.Path(r["dir"])
        for f in ("trajectory.txt", "stats.json", "ate.json", "rpe.json", "trajectory.png", "cmd.txt",
                  "result.json"):
            assert (cell / f).stat().st_size > 0, f
        cmd = (cell / "cmd.txt").read_text().splitlines()
        assert cmd[0].startswith(str(BIN / "ds3d-slam")) and "--window 3" in cmd[1]
    assert "--dynamic geometric" in (pathlib.Path(rows[1]["dir"]) / "cmd.txt").read_text()
    md = (out / "results.md").read_text()
    assert "| wx | 1 | geometric | ok |" in md and "2 cells, 0 not completed" in md
    assert (out / "results.csv").read_text().splitlines()[0].startswith("sequence,config,seed,status")
    assert (out / "ate.png").stat().st_size > 1000
    assert (out / "seq" / "wx_1" / "rgb.txt").is_file()


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # tornado make_current, Debian 12
def test_dask_cluster_matches_local_run(local, monkeypatch):
    distributed = pytest.importorskip("distributed")
    # spawned workers import ds3d from the same place as this test
    pkg = str(pathlib.Path(bench.__file__).resolve().parents[2])
    old = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([pkg] + old))
    out = local["tmp"] / "dask"
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None,
                                  silence_logs=40) as cluster:
        assert _run(local["suite"], out, "--scheduler", cluster.scheduler_address) == 0
    rows = _rows(out)
    assert len(rows) == len(local["rows"])
    for a, b in zip(local["rows"], rows):
        assert {k: v for k, v in a.items() if k not in NOT_COMPARED} == \
               {k: v for k, v in b.items() if k not in NOT_COMPARED}
        for f in ("trajectory.txt", "ate.json", "rpe.json"):
            assert (pathlib.Path(a["dir"]) / f).read_bytes() == (pathlib.Path(b["dir"]) / f).read_bytes(), f


def test_resume_runs_only_unfinished_cells(local):
    out, rows = local["out"], local["rows"]
    cells = [pathlib.Path(r["dir"]) for r in rows]
    stamps = [(c / "trajectory.txt").stat().st_mtime_ns for c in cells]
    (cells[1] / "result.json").unlink()  # as if the run had stopped during this cell
    assert _run(local["suite"], out) == 0
    assert (cells[0] / "trajectory.txt").stat().st_mtime_ns == stamps[0]  # finished: kept
    assert (cells[1] / "trajectory.txt").stat().st_mtime_ns != stamps[1]  # unfinished: run again
    assert "1 reused from an earlier run" in (out / "results.md").read_text()
    assert [r["ate_rmse"] for r in _rows(out)] == [r["ate_rmse"] for r in rows]


def test_crashed_cell_is_reported_and_others_finish(local):
    suite = _suite(local["tmp"] / "crash.json", ["none", {"name": "broken", "set": {"no.such_key": 1}}])
    assert _run(suite, local["out"]) == 1
    ok, bad = _rows(local["out"])
    assert ok["status"] == "ok" and ok["ate_rmse"] == local["rows"][0]["ate_rmse"]
    assert bad["status"].startswith("crashed") and bad["ate_rmse"] is None
    assert "unknown key 'no.such_key'" in pathlib.Path(bad["log"]).read_text()
    assert not (pathlib.Path(bad["dir"]) / "result.json").exists()  # tried again next time
    assert f"crashed (rc 2) ({bad['log']})" in (local["out"] / "results.md").read_text()


def test_bad_suites_are_refused(tmp_path, capsys):
    (tmp_path / "a.json").write_text(json.dumps({"sequences": [{"pth": "x"}]}))
    assert cli.main([str(tmp_path / "a.json"), "--dry-run"]) == 2
    assert "sequences[0]: unknown key 'pth'" in capsys.readouterr().err
    (tmp_path / "b.json").write_text(json.dumps({"sequences": ["${DS3D_BENCH_TEST_UNSET}/x"]}))
    os.environ.pop("DS3D_BENCH_TEST_UNSET", None)
    with pytest.raises(SuiteError, match="DS3D_BENCH_TEST_UNSET is not set"):
        load_suite(tmp_path / "b.json")
    (tmp_path / "c.json").write_text(json.dumps({"sequences": ["x"], "configs": ["none", "none"]}))
    with pytest.raises(SuiteError, match="used twice"):
        load_suite(tmp_path / "c.json")


def test_yaml_suite_paths_globs_and_variables(tmp_path, monkeypatch):
    pytest.importorskip("yaml")
    for name in ("seq_a", "seq_b"):
        (tmp_path / "data" / name).mkdir(parents=True)
    (tmp_path / "suites").mkdir()
    (tmp_path / "suites" / "c.yaml").write_text("htx:\n  min_score: 0.4\n")
    monkeypatch.setenv("DS3D_BENCH_TEST_DATA", str(tmp_path / "data"))
    (tmp_path / "suites" / "s.yaml").write_text(
        "sequences:\n"
        "  - glob: ${DS3D_BENCH_TEST_DATA}/seq_*\n"
        "  - {path: ../data/seq_a, name: a_slice, frames: [2, 5]}\n"
        "  - ${DS3D_BENCH_TEST_MISSING:-../nowhere}\n"
        "configs:\n  - {config: c.yaml, dynamic: htx, gate: evidence, set: {htx.report_floor: true}}\n")
    s = load_suite(tmp_path / "suites" / "s.yaml")
    assert [q["name"] for q in s["sequences"]] == ["seq_a", "seq_b", "a_slice"]
    assert s["sequences"][2]["source"] == str(tmp_path / "data" / "seq_a")
    assert len(s["warnings"]) == 1 and "nowhere" in s["warnings"][0]
    conf = s["configs"][0]
    assert conf["name"] == "htx --gate evidence --config c.yaml --set htx.report_floor=true"
    preps, cells = cli.plan(s, str(tmp_path / "out"), cli.find_tools(str(BIN)))
    assert len(cells) == 3 and len(preps) == 1 and preps[0]["recipe"]["kind"] == "slice"
    assert cells[0]["slam_args"] == ["--config", str(tmp_path / "suites" / "c.yaml"), "--dynamic", "htx",
                                     "--gate", "evidence", "--set", "htx.report_floor=true"]


def test_module_entry_point():
    r = subprocess.run([sys.executable, "-m", "ds3d.bench", "--help"], capture_output=True, text=True,
                       env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)), check=False)
    assert r.returncode == 0 and "--scheduler" in r.stdout


def test_version(capsys):
    import ds3d
    with pytest.raises(SystemExit) as e:
        cli.parse_args(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"ds3d-bench {ds3d.__version__}"


@pytest.mark.parametrize("name, synthetic_cells",
                         [("stress", 64), ("stress_heldout", 256), ("stress_fresh", 128)])
def test_shipped_stress_suites_plan_every_mode(name, synthetic_cells, tmp_path):
    # The shipped suites load and plan as documented; a file: detector joined with another source
    # takes the sequence's own detections.
    pytest.importorskip("yaml")
    s = load_suite(ROOT / "bench" / "suites" / f"{name}.yaml")
    _, cells = cli.plan(s, str(tmp_path / "out"), cli.find_tools(str(BIN)))
    synth = [c for c in cells if not c["sequence"].startswith("bonn")]
    assert len(synth) == synthetic_cells
    joined = [c for c in synth if c["config"] == "file:detections_noisy.jsonl+geometric"]
    assert len(joined) == synthetic_cells // 8
    spec = joined[0]["slam_args"][joined[0]["slam_args"].index("--dynamic") + 1]
    assert spec.startswith("file:" + str(tmp_path / "out"))
    assert spec.endswith("/detections_noisy.jsonl+geometric")
