# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Part-head fine-tune (python/ds3d/htx/finetune_part.py): per-pixel labels, head inputs equal to
the model's own, only the part head changes, and the exported file gives the C++ detector the
same boxes as before with new part logits."""
import pathlib

import numpy as np
import pytest

torch = pytest.importorskip("torch")
ds3d = pytest.importorskip("ds3d")
if not hasattr(ds3d, "synth") or not hasattr(ds3d, "SparseDetector"):
    pytest.skip("ds3d built without the synthetic generator or the detector", allow_module_level=True)

from ds3d.htx import data, finetune_part  # noqa: E402
from ds3d.htx.evaluate import _model_from_safetensors  # noqa: E402

SHIPPED = pathlib.Path(__file__).resolve().parents[2] / "models" / "htx_lite_fast.safetensors"


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("htx_tiny_finetune")
    data.generate(out, "train", frames=4, seed=11, frames_per_scene=2, shard_size=8)
    return out


def test_pixel_labels():
    s = {"human": np.array([0, 3, 3, 0, 1], np.uint8), "label": np.array([1, 1, -1, -1, 0], np.int8)}
    y, care, loc = finetune_part.pixel_labels(s)
    np.testing.assert_array_equal(y, [0, 1, 1, 0, 1])       # the pixel decides, not the box
    np.testing.assert_array_equal(care, [1, 1, 0, 1, 1])    # only human points outside boxes ignored
    np.testing.assert_array_equal(loc, [0, 1, 0, 0, 0])     # part location: human points in a box


def test_head_inputs_reproduce_the_models_part_logits(tiny):
    model = _model_from_safetensors(SHIPPED)
    s = data.HtxDataset(tiny)[0]
    with torch.no_grad():
        ref = model(torch.from_numpy(s["points"]))["part_logits"]
        mine = model.part_out(model.part_head[0](finetune_part.head_inputs(model, s)))
    np.testing.assert_allclose(mine.numpy(), ref.numpy(), atol=1e-5)


def test_only_the_part_head_changes_and_boxes_stay(tiny, tmp_path):
    out = tmp_path / "ft.safetensors"
    res = finetune_part.main(["--model", str(SHIPPED), "--data", str(tiny), "--out", str(out),
                              "--epochs", "2", "--batch", "512", "--val-fraction", "0.25",
                              "--threads", "1"], stream=open("/dev/null", "w"))
    assert len(res["loss"]) == 2 and all(np.isfinite(res["loss"]))
    assert set(res["after"]) == {"sitting", "other"}
    a, b = ds3d.SparseDetector.load(str(SHIPPED)), ds3d.SparseDetector.load(str(out))
    assert b.config.score_threshold == pytest.approx(a.config.score_threshold)
    s = data.HtxDataset(tiny)[1]
    ra, rb = a.run(s["points"], part_logits=True), b.run(s["points"], part_logits=True)
    np.testing.assert_allclose(rb["boxes"], ra["boxes"], atol=1e-5)
    assert not np.allclose(rb["part_logits"], ra["part_logits"], atol=1e-3)
    assert np.isfinite(rb["part_logits"]).all()


def test_bad_arguments(tiny, tmp_path):
    for bad in (["--epochs", "0"], ["--alpha", "1.0"], ["--lr", "0"], ["--val-fraction", "1"]):
        with pytest.raises(SystemExit):
            finetune_part.main(["--model", str(SHIPPED), "--data", str(tiny), "--out",
                                str(tmp_path / "x.safetensors")] + bad, stream=open("/dev/null", "w"))
    with pytest.raises(ValueError, match="alpha"):
        finetune_part.finetune_part(_model_from_safetensors(SHIPPED), data.HtxDataset(tiny), alpha=0.0)
    assert not (tmp_path / "x.safetensors").exists()
