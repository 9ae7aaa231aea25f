# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""scripts/eval-realtime.py on a tiny synthetic sequence: one row per mode with the medians of
its runs, byte-identical runs reported as such, --check failing on a missed target and naming
it, --realtime playing the recording at its rate with the same trajectory, a failed ATE said
with its command, modes from a suite file, bad arguments refused, absent data skipped."""
import json
import os
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("DS3D_BUILD_DIR", ROOT / "build"))
SCRIPT = ROOT / "scripts" / "eval-realtime.py"
if not all((BUILD / "bin" / t).is_file() for t in ("ds3d-slam", "ds3d-eval", "ds3d-synth")):
    pytest.skip(f"ds3d-slam / ds3d-eval / ds3d-synth not built in {BUILD}", allow_module_level=True)


def _script(*args):
    return subprocess.run([sys.executable, str(SCRIPT), "--build", str(BUILD), *args],
                          capture_output=True, text=True)


@pytest.fixture(scope="module")
def seq(tmp_path_factory):
    d = tmp_path_factory.mktemp("rt") / "wx"
    subprocess.run([str(BUILD / "bin" / "ds3d-synth"), str(d), "--scenario", "walking_xyz",
                    "--frames", "10", "--seed", "1"], check=True, capture_output=True)
    return d


def test_rows_medians_and_identical_runs(seq, tmp_path):
    done = _script("--sequences", str(seq), "--modes", "none", "geometric", "--reps", "2",
                   "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr
    rows = json.loads((tmp_path / "results.json").read_text())
    assert [r["mode"] for r in rows] == ["none", "geometric"]
    for r in rows:
        assert r["runs"] == 2 and r["identical"] and r["tracked"] == "10/10"
        assert r["fps_range"][0] <= r["fps_median"] <= r["fps_range"][1]
        assert r["p95_range"][0] <= r["p95_ms"] <= r["p95_range"][1]
        assert r["ate_rmse"] is not None and r["ate_rmse"] >= 0
        assert r["stages_wall_ms"]["track"] > 0
    assert "| wx | `geometric` |" in done.stdout


def test_check_names_the_missed_target(seq, tmp_path):
    done = _script("--sequences", str(seq), "--modes", "none", "--reps", "1", "--out",
                   str(tmp_path), "--check", "--min-fps", "1e9")
    assert done.returncode == 1
    assert "target missed: wx `none`: fps median" in done.stdout
    relaxed = _script("--sequences", str(seq), "--modes", "none", "--reps", "1", "--out",
                      str(tmp_path), "--check", "--min-fps", "1e-3", "--max-p95-ms", "1e9")
    assert relaxed.returncode == 0, relaxed.stdout


def test_realtime_plays_the_recording_and_skips_the_fps_target(seq, tmp_path):
    fast = _script("--sequences", str(seq), "--modes", "none", "--reps", "1", "--out",
                   str(tmp_path / "fast"))
    assert fast.returncode == 0, fast.stderr
    done = _script("--sequences", str(seq), "--modes", "none", "--reps", "1", "--out",
                   str(tmp_path / "live"), "--realtime", "--check", "--min-fps", "1e9",
                   "--max-p95-ms", "1e9")
    assert done.returncode == 0, done.stdout + done.stderr
    (row,) = json.loads((tmp_path / "live" / "results.json").read_text())
    assert row["realtime"] and row["input_lag_p95_ms"] >= 0
    assert "input lag p95 [ms]" in done.stdout
    # The same trajectory as when reading as fast as possible.
    assert ((tmp_path / "live" / "wx_0_1.txt").read_bytes()
            == (tmp_path / "fast" / "wx_0_1.txt").read_bytes())
    (fast_row,) = json.loads((tmp_path / "fast" / "results.json").read_text())
    assert not fast_row["realtime"] and fast_row["input_lag_p95_ms"] is None
    strict = _script("--sequences", str(seq), "--modes", "none", "--reps", "1", "--out",
                     str(tmp_path / "live"), "--realtime", "--check", "--max-p95-ms", "1e-3")
    assert strict.returncode == 1
    assert "not checked with --realtime" in strict.stdout and "p95 interval" in strict.stdout


def test_bad_arguments_and_absent_data(tmp_path):
    bad = _script("--reps", "0")
    assert bad.returncode == 2 and "--reps must be >= 1, got 0" in bad.stderr
    bad = _script("--max-p95-ms", "nan")
    assert bad.returncode == 2 and "--max-p95-ms must be > 0, got nan" in bad.stderr
    (tmp_path / "wx").mkdir()
    (tmp_path / "wx" / "rgb.txt").write_text("")
    bad = _script("--sequences", str(tmp_path / "wx"), "--suite", str(tmp_path / "no.yaml"))
    assert bad.returncode == 2 and f"--suite {tmp_path / 'no.yaml'}: " in bad.stderr
    absent = _script("--sequences", str(tmp_path / "none_here"), "--out", str(tmp_path))
    assert absent.returncode == 0 and "SKIPPED" in absent.stdout


def test_a_failed_ate_is_said_with_its_command(seq, tmp_path):
    bare = tmp_path / "bare"
    shutil.copytree(seq, bare)
    (bare / "groundtruth.txt").unlink()
    done = _script("--sequences", str(bare), "--modes", "none", "--reps", "1", "--out",
                   str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    assert "eval-realtime: no ATE for bare: '" in done.stderr and "groundtruth.txt" in done.stderr
    rows = json.loads((tmp_path / "out" / "results.json").read_text())
    assert rows[0]["ate_rmse"] is None and rows[0]["tracked"] == "10/10"
    assert "| bare | `none` |" in done.stdout


def test_modes_come_from_a_suite_file(seq, tmp_path):
    suite = tmp_path / "modes.json"
    suite.write_text(json.dumps({"name": "modes", "sequences": [str(seq)],
                                 "configs": ["none", {"dynamic": "geometric", "gate": "motion"}]}))
    done = _script("--sequences", str(seq), "--suite", str(suite), "--reps", "1", "--out",
                   str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    rows = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [r["mode"] for r in rows] == ["none", "geometric --gate motion"]
    assert "| wx | `geometric --gate motion` |" in done.stdout
