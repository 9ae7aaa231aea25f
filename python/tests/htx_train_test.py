# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""HTx trainer (python/ds3d/htx/train.py): batched forward = model forward, a few steps lower the
loss, and resuming from a checkpoint reproduces an uninterrupted run exactly."""
import json
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")
ds3d = pytest.importorskip("ds3d")
if not hasattr(ds3d, "synth") or not hasattr(ds3d, "preprocess"):
    pytest.skip("ds3d built without the synthetic generator", allow_module_level=True)

from ds3d.htx import data, train  # noqa: E402
from ds3d.htx.targets import part_targets  # noqa: E402


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("htx_tiny_train")
    data.generate(out, "train", frames=4, seed=7, frames_per_scene=2, shard_size=8)
    return out


def test_batched_forward_equals_model_forward(tiny):
    ds = data.HtxDataset(tiny)
    model = train.new_model("fast", seed=1).eval()
    samples = [ds[i] for i in range(len(ds)) if ds.num_centres(i) == model.config["num_centres"]][:2]
    assert samples, "tiny dataset has no full-size sample"
    with torch.no_grad():
        outs = train.batched_forward(model, samples)
        for s, o in zip(samples, outs):
            ref = model(torch.from_numpy(s["points"]), with_parts=True, all_layers=True)
            for a, b in zip(o["layers"], ref["layers"]):
                for k in ("center", "size", "objectness", "sem_cls_logits", "angle_logits"):
                    np.testing.assert_allclose(a[k].numpy(), b[k].numpy(), atol=2e-5, rtol=1e-5)
            np.testing.assert_allclose(o["part_logits"].numpy(), ref["part_logits"].numpy(), atol=2e-5)


def test_mirror_matches_recomputed_targets(tiny):
    ds = data.HtxDataset(tiny)
    s = next(ds[i] for i in range(len(ds)) if len(ds[i]["boxes"]))
    m = train.mirror(s)
    ref = part_targets(m["points"], m["boxes"])
    fg = s["label"] == 1
    np.testing.assert_array_equal(ref["label"][fg], 1)
    np.testing.assert_allclose(m["part"][fg], ref["part"][fg], atol=2e-3)
    assert np.all(np.abs(m["boxes"][:, 6]) <= math.pi + 1e-6)


def test_train_mode_freezes_head_batchnorm(tiny):
    ds = data.HtxDataset(tiny)
    model = train.train_mode(train.new_model("fast", seed=2, head_dropout=0.0))
    s = [ds[i] for i in range(len(ds)) if ds.num_centres(i) == model.config["num_centres"]][:1]
    heads = [m for m in model.mlp_heads.modules() if isinstance(m, torch.nn.BatchNorm1d)]
    others = [m for n, m in model.named_modules() if isinstance(m, torch.nn.BatchNorm1d) and not n.startswith("mlp_heads")]
    before = [h.running_var.clone() for h in heads]
    with torch.no_grad():
        train.batched_forward(model, s)
    assert heads and all(not h.training for h in heads) and all(o.training for o in others)
    assert all(torch.equal(a, h.running_var) for a, h in zip(before, heads))


def test_lr_schedule():
    assert train.lr_at(0, 100, 1e-3, 10) == pytest.approx(1e-4)
    assert train.lr_at(10, 100, 1e-3, 10) == pytest.approx(1e-3)
    assert train.lr_at(100, 100, 1e-3, 10) == pytest.approx(1e-3 / 50)


def _args(tiny, out, steps, extra=()):
    return ["--data", str(tiny), "--out", str(out), "--steps", str(steps), "--batch", "2",
            "--warmup", "1", "--lr", "1e-3", "--log-every", "1", "--seed", "3", *extra]


def test_few_steps_lower_the_loss(tiny, tmp_path):
    ds = data.HtxDataset(tiny)
    model = train.new_model("fast", seed=3, head_dropout=0.0)  # the run's initial model
    probe = [ds[i] for i in range(len(ds)) if ds.num_centres(i) == model.config["num_centres"]][:2]

    def loss_of(m):  # the trainer's mode (frozen BatchNorm); no dropout is active
        train.train_mode(m)
        with torch.no_grad():
            return float(train.batch_loss(m, probe, dict(train.SUNRGBD_WEIGHTS))[0])

    before = loss_of(model)
    tr = train.main(_args(tiny, tmp_path, 8, ["--head-dropout", "0"]))
    after = loss_of(tr.model)
    assert math.isfinite(before) and math.isfinite(after)
    assert after < 0.9 * before
    assert (tmp_path / "checkpoint.pt").exists() and (tmp_path / "loss.png").stat().st_size > 1000
    assert len((tmp_path / "log.jsonl").read_text().splitlines()) == 8


def test_resume_gives_the_same_state(tiny, tmp_path):
    straight = train.main(_args(tiny, tmp_path / "a", 4))
    train.main(_args(tiny, tmp_path / "b", 2))
    resumed = train.main(_args(tiny, tmp_path / "b", 4))  # picks up checkpoint.pt at step 2
    assert resumed.step == straight.step == 4
    sa, sb = straight.model.state_dict(), resumed.model.state_dict()
    for k in sa:
        assert torch.equal(sa[k], sb[k]), k
    assert [h["loss"] for h in straight.history] == [h["loss"] for h in resumed.history]


def test_checkpoint_model_exports(tiny, tmp_path):
    train.main(_args(tiny, tmp_path, 1))
    model = train.load_checkpoint_model(tmp_path / "checkpoint.pt")
    from ds3d.htx import reference_detect, read_safetensors
    train.main(["export", "--checkpoint", str(tmp_path / "checkpoint.pt"), "--out", str(tmp_path / "w.safetensors"),
                "--threshold", "0.35"])
    tensors, meta = read_safetensors(tmp_path / "w.safetensors")
    assert meta["format"] == "ds3d-htx" and all(np.isfinite(v).all() for v in tensors.values())
    assert json.loads(meta["config"])["score_threshold"] == pytest.approx(0.35)
    with pytest.raises(ValueError, match="threshold"):
        train.export_checkpoint(tmp_path / "checkpoint.pt", tmp_path / "x.safetensors", 1.5)
    s = data.HtxDataset(tiny)[0]
    out = reference_detect(model, s["points"])
    assert out.shape[1] == 9 and np.isfinite(out).all()


def test_init_fine_tunes_the_exported_network(tiny, tmp_path):
    # A weights file to start from: one step of a fresh run, exported.
    train.main(_args(tiny, tmp_path / "base", 1))
    w = tmp_path / "w.safetensors"
    train.export_checkpoint(tmp_path / "base" / "checkpoint.pt", w, 0.5)
    # Fine-tuning with a vanishing learning rate must export the same network again: every
    # BatchNorm keeps the folded identity statistics (batch statistics would replace them).
    tr = train.main(_args(tiny, tmp_path / "ft", 2, ["--init", str(w), "--lr", "1e-12", "--head-dropout", "0"]))
    assert all(not m.training for m in tr.model.modules() if isinstance(m, torch.nn.BatchNorm1d))
    w2 = tmp_path / "w2.safetensors"
    train.export_checkpoint(tmp_path / "ft" / "checkpoint.pt", w2, 0.5)
    from ds3d.htx import read_safetensors
    a, _ = read_safetensors(w)
    b, _ = read_safetensors(w2)
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_allclose(a[k], b[k], rtol=1e-5, atol=1e-6, err_msg=k)
    # With a real learning rate the fine-tune moves the weights.
    tr = train.main(_args(tiny, tmp_path / "ft2", 2, ["--init", str(w), "--lr", "1e-3"]))
    train.export_checkpoint(tmp_path / "ft2" / "checkpoint.pt", w2, 0.5)
    c, _ = read_safetensors(w2)
    assert any(not np.allclose(a[k], c[k]) for k in a)


def test_bad_arguments_exit(tiny, tmp_path):
    with pytest.raises(SystemExit):
        train.parse_args(["--data", str(tiny), "--out", str(tmp_path), "--steps", "0"])
    with pytest.raises(SystemExit):
        train.parse_args(["--data", str(tiny), "--out", str(tmp_path), "--lr", "-1"])
