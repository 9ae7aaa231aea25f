# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.SlamConfig (python/ds3d/config.py over include/ds3d/slam/config.hpp): attributes, keys,
files, errors, and run_slam driven by it."""
import numpy as np
import pytest

import ds3d


def test_attributes_and_keys_are_the_same_fields():
    cfg = ds3d.SlamConfig(dynamic="htx", gate="motion", htx__min_score=0.4)
    assert cfg.dynamic == "htx" and cfg["dynamic.source"] == "htx"
    assert cfg["dynamic.gate"] == "motion"
    assert cfg.htx.min_score == pytest.approx(0.4)
    cfg.htx.report_floor = True
    cfg["frontend.orb.num_features"] = 1200
    assert cfg["htx.report_floor"] is True
    assert cfg.frontend.orb.num_features == 1200
    d = cfg.to_dict()
    assert len(d) == len(ds3d.config_keys()) > 90
    assert d["frontend.fuse_neighbors"] is False and isinstance(d["frontend.bf"], float)
    assert ("htx.report_floor", "true") in cfg.settings()
    other = ds3d.SlamConfig().update(d)
    assert other == cfg and other.copy() == cfg
    assert "min_score" in dir(cfg.htx)
    assert cfg.frontend_config().fuse_neighbors is False


def test_bad_keys_and_values_name_them():
    cfg = ds3d.SlamConfig()
    with pytest.raises(ValueError, match="htx.min_scor"):
        cfg["htx.min_scor"] = 1
    with pytest.raises(ValueError, match="abc"):
        cfg["htx.min_score"] = "abc"
    with pytest.raises(AttributeError):
        cfg.htx.nope  # noqa: B018
    with pytest.raises(KeyError):
        cfg["nope"]  # noqa: B018
    cfg.htx.min_score = 2.0  # parses; the range is validate()'s
    with pytest.raises(ValueError, match="min_score"):
        cfg.validate()


def test_files_and_dump(tmp_path):
    p = tmp_path / "run.yaml"
    p.write_text("dynamic:\n  source: geometric\nhtx.detect_every: 3\nfrontend:\n  bf: 41.5\n")
    cfg = ds3d.SlamConfig.from_file(p, gate="evidence")
    assert cfg.dynamic == "geometric" and cfg.htx.detect_every == 3
    assert cfg.frontend.bf == 41.5 and cfg.gate == "evidence"
    q = tmp_path / "dump.yaml"
    q.write_text(cfg.dump())
    assert ds3d.SlamConfig.from_file(q) == cfg
    (tmp_path / "bad.yaml").write_text("htx:\n  min_score: x\n")
    with pytest.raises(ValueError, match="bad.yaml"):
        ds3d.SlamConfig.from_file(tmp_path / "bad.yaml")
    with pytest.raises(RuntimeError):
        ds3d.SlamConfig.from_file(tmp_path / "missing.yaml")


def test_run_slam_takes_the_config(tmp_path):
    ds3d.synth.generate(tmp_path, frames=6, seed=3, humans=1)
    a = ds3d.run_slam(tmp_path, dynamic="geometric", threaded=False)
    cfg = ds3d.SlamConfig(dynamic="geometric")
    cfg.pipeline.threaded = False
    b = ds3d.run_slam(tmp_path, config=cfg)
    c = ds3d.run_slam(tmp_path, config={"dynamic.source": "geometric"})
    assert np.array_equal(a, b) and np.array_equal(a, c)
    with pytest.raises(TypeError, match="draws"):
        ds3d.run_slam(tmp_path, dynamic="htx", draws=2)
    with pytest.raises(ValueError, match="gate"):
        ds3d.run_slam(tmp_path, dynamic="none", gate="motion")
