# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""CPU trainer of HTx-lite on the synthetic humanoid data of ds3d.htx.data.

    python3 -m ds3d.htx.train --data DIR/train --out DIR/run --steps 6000 --threads 1 \\
        --max-minutes 70

Recipe (docs/htx_training.md): AdamW (3DETR: lr 5e-4, weight decay 0.1, gradient-norm clip 0.1),
linear warm-up then cosine decay to lr/50 over ``--steps``; ``--batch`` scenes per optimizer step
(one batched forward, batched_forward); losses of seed eq.
1 (3DETR set loss with Hungarian matching, all decoder layers) + ``--part-weight`` x seed eq. 3
(Part-A2 focal foreground + part-location BCE) on the stored targets; random left-right mirror.

Deterministic for a seed and thread count; ``--out`` holds ``checkpoint.pt`` (written atomically
every ``--ckpt-minutes`` and at the end; the run resumes from it), ``log.jsonl`` (one line per
step), ``loss.png`` and, with ``--snapshot-steps``, ``checkpoint_<step>.pt`` copies.
"""
import argparse
import json
import math
import os
import pathlib
import sys
import time

import numpy as np
import torch

from .config import make_config
from .data import HtxDataset, shard_files
from .losses import SUNRGBD_WEIGHTS, detection_loss, part_loss
from .model import HTx, fourier_embedding
from .targets import box_targets


def new_model(profile="fast", seed=0, dropout=0.0, head_dropout=0.1):
    """A freshly initialised HTx (PyTorch default init, BatchNorm at identity) for training."""
    torch.manual_seed(seed)
    return set_head_dropout(HTx(make_config(profile), dropout=dropout), head_dropout)


def set_head_dropout(model, p):
    """Sets the dropout probability of the query heads (``mlp_heads``) to ``p``; returns model."""
    for name, m in model.named_modules():
        if isinstance(m, torch.nn.Dropout) and name.startswith("mlp_heads"):
            m.p = p
    return model


def init_model(path, seed=0, head_dropout=0.1):
    """An HTx to fine-tune from an exported weights file (``--init``): the exported network,
    whose BatchNorms were folded at export (identity statistics carrying the folded bias)."""
    from .evaluate import _model_from_safetensors

    torch.manual_seed(seed)
    return set_head_dropout(_model_from_safetensors(path), head_dropout)


def fine_tune_mode(model):
    """Training mode with every BatchNorm frozen: a model from ``init_model`` keeps its folded
    statistics, so that the network trained is the network exported (batch statistics would
    replace the identity normalisation the folded weights assume)."""
    model.train()
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm1d):
            m.eval()
    return model


def train_mode(model):
    """Training mode with the BatchNorms of the five query heads frozen at their initial
    statistics (mean 0, variance 1, i.e. learned affine maps). In the heads, batch statistics
    come from one scene's 64 queries, where some channels have almost no spread: the network then
    learns to amplify differences that the running averages used at inference do not reproduce
    (observed: every query at objectness 1 in eval mode after 100 steps). The set-abstraction,
    projection and part-head BatchNorms see thousands of rows per batch and stay in training mode
    (freezing them too leaves the point features tiny and the decoder collapses to one box).
    """
    model.train()
    for m in model.mlp_heads.modules():
        if isinstance(m, torch.nn.BatchNorm1d):
            m.eval()
    return model


def mirror(sample):
    """Left-right mirror (x -> -x) of one sample: boxes theta -> pi - theta, part y -> 1 - y
    (the box's local y axis flips, its local x axis does not; spec §2)."""
    s = dict(sample)
    s["points"] = sample["points"] * np.array([-1, 1, 1], np.float32)
    b = sample["boxes"].copy()
    b[:, 0] = -b[:, 0]
    b[:, 6] = np.mod(math.pi - b[:, 6] + math.pi, 2 * math.pi) - math.pi
    s["boxes"] = b
    part = sample["part"].copy()
    fg = sample["label"] > 0
    part[fg, 1] = 1.0 - part[fg, 1]
    s["part"] = part
    return s


def encode_stored(model, samples):
    """The set abstraction and encoder of ``model`` on stored samples, as one batch, with their
    stored network selections (data.network_indices). Every scene must have the same token count.
    Returns (xyz list of [n, 3], centres [B, t, 3], enc [t, B, d], scene_min [B, 3],
    scene_max [B, 3])."""
    c = model.config
    xyz = [torch.from_numpy(np.ascontiguousarray(s["points"], dtype=np.float32)) for s in samples]
    cidx = [torch.from_numpy(np.asarray(s["centre_idx"], dtype=np.int64)) for s in samples]
    if any(len(ci) != len(cidx[0]) for ci in cidx):
        raise ValueError("ds3d.htx.train.encode_stored: scenes need equal token counts")
    centres = torch.stack([x[ci] for x, ci in zip(xyz, cidx)])  # [B, t, 3]
    grouped = torch.stack([(x[torch.from_numpy(np.asarray(s["group"], dtype=np.int64))] - x[ci][:, None, :])
                           / c["sa_radius"] for x, ci, s in zip(xyz, cidx, samples)])  # [B, t, s, 3]
    feats = grouped
    for layer in model.pre_encoder:
        feats = layer(feats)
    feats = feats.max(dim=2).values  # [B, t, d]
    enc = feats.transpose(0, 1)  # [t, B, d]
    for layer in model.encoder:
        enc = layer(enc)
    smin = torch.stack([x.min(dim=0).values for x in xyz])  # [B, 3]
    smax = torch.stack([x.max(dim=0).values for x in xyz])
    return xyz, centres, enc, smin, smax


def part_head_rows(enc_scene, xyz, sample, scene_min, scene_max):
    """The part head's input rows [n, d + 3] of one scene (``model.part_logits``): its encoder
    features enc_scene [t, d] interpolated at every point with the stored 3 nearest tokens and
    weights, then the point's xyz normalised to the scene box."""
    nn_idx = torch.from_numpy(np.asarray(sample["nn_idx"], dtype=np.int64))
    nn_w = torch.from_numpy(np.asarray(sample["nn_w"], dtype=np.float32))
    f = (enc_scene[nn_idx] * nn_w[..., None]).sum(dim=1)
    extent = torch.clamp(scene_max - scene_min, min=1e-6)
    return torch.cat([f, (xyz - scene_min) / extent], dim=1)


def batched_forward(model, samples, with_parts=True):
    """model.forward for a list of stored samples at once, using their stored network selections
    (data.network_indices): the set abstraction, encoder, projection and decoder run as one batch
    (PyTorch MultiheadAttention's [L, N, E] layout), heads and box decoding per scene
    (``model.heads``), the part head on all points of the batch. Every scene must have the same
    token and query counts. Returns one dict per scene with ``layers`` (all decoder layers),
    ``scene_min``, ``scene_max`` and ``part_logits``; in eval mode equal to ``model(xyz)``.
    """
    nq = len(samples[0]["query_idx"])
    if any(len(s["query_idx"]) != nq for s in samples):
        raise ValueError("ds3d.htx.train.batched_forward: scenes need equal token and query counts")
    xyz, centres, enc, smin, smax = encode_stored(model, samples)
    memory = enc
    for layer in model.encoder_to_decoder_projection:
        memory = layer(memory)  # [t, B, d]
    qxyz = torch.stack([centres[b, torch.from_numpy(s["query_idx"])] for b, s in enumerate(samples)])
    qpos = torch.stack([fourier_embedding(qxyz[b], smin[b], smax[b], model.gauss_B)
                        for b in range(len(samples))]).transpose(0, 1)  # [q, B, d]
    for lin in model.query_projection:
        qpos = torch.relu(lin(qpos))
    mpos = torch.stack([fourier_embedding(centres[b], smin[b], smax[b], model.gauss_B)
                        for b in range(len(samples))]).transpose(0, 1)  # [t, B, d]
    tq = torch.zeros_like(qpos)
    outs = [{"scene_min": smin[b], "scene_max": smax[b], "layers": []} for b in range(len(samples))]
    for layer in model.decoder:
        tq = layer(tq, memory, qpos, mpos)
        normed = model.decoder_norm(tq)  # [q, B, d]
        for b in range(len(samples)):
            outs[b]["layers"].append(model.heads(normed[:, b, :], qxyz[b], smin[b], smax[b]))
    if with_parts:
        h = torch.cat([part_head_rows(enc[:, b, :], x, s, smin[b], smax[b])
                       for b, (x, s) in enumerate(zip(xyz, samples))])  # [sum n, d + 3]
        for layer in model.part_head:
            h = layer(h)
        logits = model.part_out(h)
        start = 0
        for b, x in enumerate(xyz):
            outs[b]["part_logits"] = logits[start:start + len(x)]
            start += len(x)
    return outs


def batch_loss(model, samples, weights, scenes=None, count_fg=None):
    """Mean over the scenes of seed eq. 1 (all decoder layers) plus seed eq. 3 on all points of
    the batch at once (weighted by weights['part_fg'/'part_loc']): Part-A2 normalises by the
    batch's number of foreground points (OpenPCDet's pos_normalizer), so a scene without people
    does not divide its background loss by 1. Returns (loss, mean components).
    Data-parallel share (ds3d.htx.distributed): ``scenes`` is the global batch size the
    detection loss is divided by, ``count_fg(n)`` the global foreground count of a local n."""
    denom = len(samples) if scenes is None else scenes
    with_parts = weights["part_fg"] > 0 or weights["part_loc"] > 0
    outs = batched_forward(model, samples, with_parts)
    total, comps = 0.0, {}
    for out, s in zip(outs, samples):
        tgt = box_targets(s["boxes"], s["classes"], out["scene_min"].detach().numpy(),
                          out["scene_max"].detach().numpy(), model.config["num_angle_bins"])
        loss, parts = detection_loss(out["layers"], tgt, weights)
        total = total + loss / denom
        for k, v in parts.items():
            comps[k] = comps.get(k, 0.0) + v / denom
    if with_parts:
        logits = torch.cat([o["part_logits"] for o in outs])
        label = np.concatenate([s["label"] for s in samples]).astype(np.int64)
        part = np.concatenate([s["part"] for s in samples])
        npos = None if count_fg is None else max(count_fg(int((label > 0).sum())), 1)
        pl, pp = part_loss(logits, label, part, weights, npos)
        total = total + pl
        comps.update(pp)
    return total, comps


def lr_at(step, total, base, warmup):
    """Linear warm-up for ``warmup`` steps, then cosine from base to base/50 at ``total``."""
    if step < warmup:
        return base * (step + 1) / warmup
    t = min(1.0, (step - warmup) / max(1, total - warmup))
    lo = base / 50
    return lo + 0.5 * (base - lo) * (1 + math.cos(math.pi * t))


class Trainer:
    """Holds model, optimiser, data order and history; ``state_dict``/``load_state_dict`` cover
    everything needed to resume bit-identically (model, optimiser, both RNGs, step, history).
    With a ``ctx`` (ds3d.htx.distributed.DistContext) it is one rank of a data-parallel run:
    every rank draws the same global batch and computes its share under DistributedDataParallel."""

    def __init__(self, dataset, args, ctx=None):
        self.ds = dataset
        self.args = args
        self.ctx = ctx
        if getattr(args, "init", None):
            self.model = fine_tune_mode(init_model(args.init, args.seed, args.head_dropout))
        else:
            self.model = train_mode(new_model(args.profile, args.seed, args.dropout, args.head_dropout))
        self.opt = torch.optim.AdamW(self.model.parameters(), lr=args.lr, weight_decay=args.weight_decay)
        self.rng = np.random.default_rng(args.seed)
        self.step = 0
        self.history = []
        self.weights = dict(SUNRGBD_WEIGHTS, part_fg=args.part_weight, part_loc=args.part_weight)
        self.order = np.zeros(0, np.int64)
        self.cursor = 0
        self.set_dataset(dataset)
        self.ddp = None
        if ctx is not None:
            from . import distributed

            if args.batch % ctx.world:
                raise ValueError(f"ds3d.htx.train: --batch {args.batch} is not divisible by the "
                                 f"{ctx.world} processes")
            distributed.sync_batchnorm(self.model, ctx)
            self.ddp = distributed.wrap(self.model, self.weights, batch_loss, ctx, args.batch)

    def set_dataset(self, dataset):
        # batched_forward needs equal token counts: scenes with fewer points than tokens are skipped
        self.ds = dataset
        t = self.model.config["num_centres"]
        self.usable = np.array([i for i in range(len(dataset)) if dataset.num_centres(i) == t], np.int64)
        if len(self.usable) == 0:
            raise ValueError(f"ds3d.htx.train: no sample of {len(dataset)} has {t} tokens")

    def next_indices(self, n):
        out = []
        while len(out) < n:
            if self.cursor >= len(self.order):
                if self.args.reload_data and len(shard_files(self.args.data)) != len(self.ds.shards):
                    self.set_dataset(HtxDataset(self.args.data))  # new shards appeared: new epoch uses them
                self.order = self.usable[self.rng.permutation(len(self.usable))]
                self.cursor = 0
            out.append(int(self.order[self.cursor]))
            self.cursor += 1
        return out

    def train_step(self):
        a = self.args
        lr = lr_at(self.step, a.steps, a.lr, a.warmup)
        for g in self.opt.param_groups:
            g["lr"] = lr
        self.opt.zero_grad(set_to_none=True)
        idx = self.next_indices(a.batch)
        flips = [self.rng.random() < 0.5 for _ in idx]  # every rank draws the whole global batch
        if self.ctx is not None:
            idx, flips = self.ctx.shard(idx), self.ctx.shard(flips)
        samples = [mirror(self.ds[i]) if f else self.ds[i] for i, f in zip(idx, flips)]
        if self.ctx is None:
            loss, comps = batch_loss(self.model, samples, self.weights)
            loss.backward()
            total = float(loss)
        else:  # DDP averages the gradients: world x this rank's share gives the global loss's
            loss, comps = self.ddp(samples)
            (loss * self.ctx.world).backward()
            keys = sorted(comps)
            sums = self.ctx.sum_floats([float(loss)] + [comps[k] for k in keys])
            total, comps = sums[0], dict(zip(keys, sums[1:]))
        gn = torch.nn.utils.clip_grad_norm_(self.model.parameters(), a.clip)
        self.opt.step()
        self.step += 1
        last = self.model.config["dec_layers"] - 1
        rec = {"step": self.step, "loss": total, "lr": lr, "grad_norm": float(gn),
               "sem_cls": comps.get(f"sem_cls_{last}", 0.0), "center": comps.get(f"center_{last}", 0.0),
               "size": comps.get(f"size_{last}", 0.0), "part_fg": comps.get("part_fg", 0.0),
               "part_loc": comps.get("part_loc", 0.0)}
        self.history.append(rec)
        return rec

    def state_dict(self):
        st = {"model": self.model.state_dict(), "opt": self.opt.state_dict(),
              "rng": self.rng.bit_generator.state, "torch_rng": torch.get_rng_state(),
              "step": self.step, "history": self.history, "order": self.order, "cursor": self.cursor,
              "config": self.model.config, "args": vars(self.args)}
        if self.ctx is not None:  # collective: every rank calls it; each rank's dropout stream
            st["torch_rng_ranks"] = self.ctx.gather_objects(torch.get_rng_state())
        return st

    def load_state_dict(self, st):
        self.model.load_state_dict(st["model"])
        self.opt.load_state_dict(st["opt"])
        self.rng.bit_generator.state = st["rng"]
        ranks = st.get("torch_rng_ranks")
        if self.ctx is not None and ranks is not None and len(ranks) == self.ctx.world:
            torch.set_rng_state(ranks[self.ctx.rank])
        else:
            torch.set_rng_state(st["torch_rng"])
        self.step, self.history = st["step"], st["history"]
        self.order, self.cursor = np.asarray(st["order"]), st["cursor"]

    def save(self, path):
        """Writes the checkpoint atomically (rank 0 only; every rank must call it)."""
        st = self.state_dict()
        if self.ctx is None or self.ctx.is_main:
            tmp = str(path) + ".tmp"
            torch.save(st, tmp)
            os.replace(tmp, path)
        if self.ctx is not None:
            self.ctx.barrier()


def load_checkpoint_model(path):
    """The model of a checkpoint, in eval mode (for evaluation and export)."""
    st = torch.load(path, map_location="cpu")
    model = HTx(st["config"])
    model.load_state_dict(st["model"])
    return model.eval()


def export_checkpoint(checkpoint, out, threshold):
    """Writes the weights file of a checkpoint (BatchNorm folded, ds3d.htx.export) with the
    deployment objectness threshold ``threshold`` in [0, 1) in its config. Returns the model."""
    from .weights import export

    if not 0 <= threshold < 1:
        raise ValueError(f"ds3d.htx.train.export_checkpoint: threshold must be in [0, 1) (got {threshold})")
    model = load_checkpoint_model(checkpoint)
    model.config["score_threshold"] = float(threshold)
    pathlib.Path(out).parent.mkdir(parents=True, exist_ok=True)
    export(model, out)
    return model


def plot_loss(history, path):
    """Loss curve PNG: total loss and main components (moving average over 50 steps)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not history:
        return
    steps = np.array([h["step"] for h in history])
    fig, ax = plt.subplots(figsize=(7, 4), dpi=100)
    for key in ("loss", "sem_cls", "center", "size", "part_fg", "part_loc"):
        v = np.array([h[key] for h in history], dtype=np.float64)
        w = min(50, len(v))
        sm = np.convolve(v, np.ones(w) / w, mode="valid")
        ax.plot(steps[w - 1:], sm, label=key, lw=1.5 if key == "loss" else 1.0)
    ax.set_yscale("log")
    ax.set_xlabel("optimizer step")
    ax.set_ylabel("loss (moving average, 50 steps)")
    ax.set_title("HTx-lite fast: training loss")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def progress(step, total, t0, rec, stream):
    """One progress-bar line: a bar, steps, rate, ETA and a smoothed loss."""
    frac = step / max(total, 1)
    el = time.time() - t0
    bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
    eta = el / max(frac, 1e-9) - el if frac > 0 else float("nan")
    end = "\r" if stream.isatty() else "\n"
    stream.write(f"[{bar}] {step}/{total} {el / 60:5.1f} min, eta {eta / 60:5.1f} min, "
                 f"loss {rec['loss']:.3f} (cls {rec['sem_cls']:.3f} ctr {rec['center']:.3f} "
                 f"part {rec['part_fg'] + rec['part_loc']:.3f}){end}")
    stream.flush()


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, help="folder of training .npz shards (ds3d.htx.make_dataset)")
    p.add_argument("--out", required=True, help="run folder: checkpoint.pt, log.jsonl, loss.png")
    p.add_argument("--profile", default="fast", choices=("fast", "quality"))
    p.add_argument("--steps", type=int, default=6000, help="optimizer steps of the schedule")
    p.add_argument("--batch", type=int, default=4, help="scenes per optimizer step")
    p.add_argument("--lr", type=float, default=5e-4)
    p.add_argument("--weight-decay", type=float, default=0.1)
    p.add_argument("--warmup", type=int, default=200)
    p.add_argument("--clip", type=float, default=0.1, help="gradient-norm clip (3DETR: 0.1)")
    p.add_argument("--dropout", type=float, default=0.0, help="transformer dropout")
    p.add_argument("--head-dropout", type=float, default=0.1)
    p.add_argument("--part-weight", type=float, default=1.0, help="weight of seed eq. 3 (0: ablation)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=1, help="torch intra-op threads")
    p.add_argument("--stop-step", type=int, default=0,
                   help="stop at this step although the schedule runs to --steps (equal-budget ablations)")
    p.add_argument("--max-minutes", type=float, default=0.0, help="stop (and checkpoint) after this; 0 = no limit")
    p.add_argument("--ckpt-minutes", type=float, default=5.0)
    p.add_argument("--snapshot-steps", default="", help="comma list: keep checkpoint_<step>.pt copies")
    p.add_argument("--log-every", type=int, default=10)
    p.add_argument("--reload-data", action="store_true",
                   help="at each epoch start, reload --data if shards were added (train while generating)")
    p.add_argument("--no-resume", action="store_true", help="ignore an existing checkpoint.pt")
    p.add_argument("--init", default="",
                   help="fine-tune: start from this exported weights file (.safetensors; its profile, "
                        "every BatchNorm frozen) instead of a fresh model")
    a = p.parse_args(argv)
    for name in ("steps", "batch", "threads", "log_every"):
        if getattr(a, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1 (got {getattr(a, name)})")
    for name in ("lr", "clip"):
        if not getattr(a, name) > 0:
            p.error(f"--{name} must be > 0 (got {getattr(a, name)})")
    if a.part_weight < 0 or a.max_minutes < 0 or a.warmup < 0 or a.stop_step < 0:
        p.error("--part-weight, --max-minutes, --stop-step and --warmup must be >= 0")
    return a


def main(argv=None, stream=sys.stderr):
    """Runs (or resumes) a training run; returns the Trainer. ``export --checkpoint C --out W
    --threshold T`` instead writes the weights file of a checkpoint (export_checkpoint)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["export"]:
        p = argparse.ArgumentParser(prog="python3 -m ds3d.htx.train export")
        p.add_argument("--checkpoint", required=True)
        p.add_argument("--out", required=True, help="weights file (.safetensors)")
        p.add_argument("--threshold", type=float, required=True, help="deployment objectness threshold")
        e = p.parse_args(argv[1:])
        export_checkpoint(e.checkpoint, e.out, e.threshold)
        return None
    a = parse_args(argv)
    from . import distributed

    ctx = distributed.init_from_env()
    try:
        return _run(a, ctx, stream if ctx is None or ctx.is_main else open(os.devnull, "w"))
    finally:
        distributed.shutdown(ctx)


def _run(a, ctx, stream):
    """The training loop of main: rank 0 (or the single process) writes log, plot and checkpoints."""
    main_rank = ctx is None or ctx.is_main
    torch.set_num_threads(a.threads)
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    ds = HtxDataset(a.data)
    tr = Trainer(ds, a, ctx)
    ck = out / "checkpoint.pt"
    if ck.exists() and not a.no_resume:
        tr.load_state_dict(torch.load(ck, map_location="cpu"))
        stream.write(f"resumed from {ck} at step {tr.step}\n")
    snaps = {int(s) for s in a.snapshot_steps.split(",") if s.strip()}
    t0, c0 = time.time(), time.process_time()
    last_ck = t0
    log = open(out / "log.jsonl" if main_rank else os.devnull, "a", encoding="utf-8")
    try:
        end = min(a.steps, a.stop_step) if a.stop_step > 0 else a.steps
        while tr.step < end:
            rec = tr.train_step()
            rec["time_s"] = round(time.time() - t0, 2)
            rec["cpu_s"] = round(time.process_time() - c0, 2)  # this process's CPU time (shared machine)
            log.write(json.dumps(rec) + "\n")
            if not all(math.isfinite(v) for v in (rec["loss"], rec["grad_norm"])):
                raise FloatingPointError(f"ds3d.htx.train: non-finite loss at step {tr.step}: {rec}")
            if tr.step % a.log_every == 0 or tr.step == a.steps:
                log.flush()
                progress(tr.step, a.steps, t0, rec, stream)
            if tr.step in snaps:
                tr.save(out / f"checkpoint_{tr.step}.pt")
            timeout = a.max_minutes > 0 and time.time() - t0 > 60 * a.max_minutes
            save = time.time() - last_ck > 60 * a.ckpt_minutes or tr.step == end or timeout
            if ctx is not None:  # clock decisions are rank 0's, so that every rank saves / stops
                save, timeout = ctx.broadcast_flags([save, timeout])
            if save:
                tr.save(ck)
                if main_rank:
                    plot_loss(tr.history, out / "loss.png")
                last_ck = time.time()
            if timeout:
                stream.write(f"\nstopped by --max-minutes at step {tr.step}\n")
                break
    finally:
        log.close()
    if tr.step > 0:
        tr.save(ck)
        if main_rank:
            plot_loss(tr.history, out / "loss.png")
    stream.write("\n")
    return tr


if __name__ == "__main__":
    main()
