# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Re-fits the HTx part head on per-pixel human labels, everything else frozen.

The main training (ds3d.htx.train) labels a point foreground when it lies in a ground-truth box
and ignores the box's other points (chair, wall behind): the head was never told that the seat
under a seated person is background, and calls it foreground. Here every input point gets the
label of the pixel it was drawn from (``human`` of the stored samples): human = 1, anything else
= 0, and only human points outside every labelled box are ignored (as in the main training). The
backbone, decoder and box heads are frozen, so the boxes do not change; only ``part_head`` and
``part_out`` are trained, on the head inputs (3-NN interpolated encoder features and normalised
xyz) computed once per sample. Loss: the Part-A2 foreground focal loss normalised by positives
(``--alpha``, default 0.5, i.e. no class weighting: it gave a higher point F1 on the held-out
scenes than Part-A2's 0.25, see models/README.md) plus the part-location BCE on the human points inside boxes.

Usage::

    python3 -m ds3d.htx.finetune_part --model models/htx_lite_fast.safetensors \
        --data WORK/train --out models/htx_lite_fast.safetensors [--epochs 6] [--alpha 0.5]

The last ``--val-fraction`` of the samples (whole scenes: frames are stored scene by scene) is
held out; point precision / recall at probability 0.5 on it, split into frames with and without a
seated humanoid, are printed before and after each epoch and returned.
"""
import argparse
import copy
import math
import pathlib
import sys
import time

import numpy as np
import torch
import torch.nn.functional as F

from .data import HtxDataset
from .losses import sigmoid_focal_loss
from .train import encode_stored, part_head_rows

SITTING_COLUMN = 2  # data.BOX_META_COLUMNS


def pixel_labels(sample):
    """(target [n] float32 in {0, 1}, care [n] float32, location mask [n] float32) of a stored
    sample: target = the point's pixel shows a human; care = 0 only for human points the main
    training ignored (outside every labelled box); location mask = human points inside a box."""
    human = np.asarray(sample["human"]) > 0
    label = np.asarray(sample["label"])
    care = ~(human & (label < 0))
    return human.astype(np.float32), care.astype(np.float32), ((label > 0) & human).astype(np.float32)


@torch.no_grad()
def head_inputs(model, sample):
    """The part head's input rows [n, d + 3] of one stored sample (its stored network selections),
    as ``model.part_logits`` builds them (train.encode_stored, train.part_head_rows); the model
    must be in eval mode."""
    xyz, _, enc, smin, smax = encode_stored(model, [sample])
    return part_head_rows(enc[:, 0, :], xyz[0], sample, smin[0], smax[0])


def _head_logits(head, out, rows):
    for layer in head:
        rows = layer(rows)
    return out(rows)


def point_metrics(head, out, H, Y, CARE, rows):
    """(precision, recall, tp, fp, fn) of foreground at probability 0.5 over ``rows``."""
    tp = fp = fn = 0
    with torch.no_grad():
        for k in range(0, len(rows), 65536):
            j = rows[k:k + 65536]
            p = _head_logits(head, out, H[j].float())[:, 0] > 0.0
            y, care = Y[j] > 0.5, CARE[j] > 0.5
            tp += int((p & y & care).sum())
            fp += int((p & ~y & care).sum())
            fn += int((~p & y & care).sum())
    return tp / max(tp + fp, 1), tp / max(tp + fn, 1), tp, fp, fn


def finetune_part(model, dataset, epochs=6, lr=1e-3, alpha=0.5, batch=16384, val_fraction=0.1,
                  seed=0, stream=None):
    """Trains ``model.part_head`` and ``model.part_out`` in place on ``dataset`` (HtxDataset)
    with per-pixel labels (module doc); the rest of ``model`` is untouched. Returns a dict with
    ``before`` and ``after`` val metrics ({'sitting': (p, r, tp, fp, fn), 'other': ...}) and the
    mean training loss of each epoch (``loss``). Deterministic for ``seed``."""
    if epochs < 1 or not lr > 0 or not 0 < alpha < 1 or batch < 1 or not 0 <= val_fraction < 1:
        raise ValueError("ds3d.htx.finetune_part.finetune_part: need epochs >= 1, lr > 0, 0 < alpha < 1, "
                         f"batch >= 1, 0 <= val_fraction < 1 (got {epochs}, {lr}, {alpha}, {batch}, "
                         f"{val_fraction})")
    log = stream.write if stream is not None else (lambda s: None)
    model.eval()
    n = len(dataset)
    first_val = min(n - 1, int(math.floor(n * (1.0 - val_fraction)))) if val_fraction > 0 else n
    H, Y, CARE, LOC, LOCM, SIT, VAL = [], [], [], [], [], [], []
    t0 = time.time()
    for i in range(n):
        s = dataset[i]
        H.append(head_inputs(model, s).half())  # half: the rows of 3,000 frames fit in ~3 GB
        y, care, locm = pixel_labels(s)
        Y.append(torch.from_numpy(y))
        CARE.append(torch.from_numpy(care))
        LOC.append(torch.from_numpy(np.asarray(s["part"], dtype=np.float32)))
        LOCM.append(torch.from_numpy(locm))
        meta = np.asarray(s["box_meta"]).reshape(-1, 6)
        SIT.append(torch.full((len(y),), bool((meta[:, SITTING_COLUMN] > 0).any()), dtype=torch.bool))
        VAL.append(torch.full((len(y),), i >= first_val, dtype=torch.bool))
    H, Y, CARE, LOC, LOCM = (torch.cat(t) for t in (H, Y, CARE, LOC, LOCM))
    SIT, VAL = torch.cat(SIT), torch.cat(VAL)
    log(f"finetune_part: {n} samples, {len(Y)} points ({int(Y.sum())} human), head inputs in "
        f"{time.time() - t0:.0f} s\n")
    head, out = model.part_head, model.part_out
    for m in head.modules():  # folded or not, the BatchNorm statistics stay as they are
        if isinstance(m, torch.nn.BatchNorm1d):
            m.eval()

    def val_metrics():
        r = {}
        for name, rows in (("sitting", VAL & SIT), ("other", VAL & ~SIT)):
            r[name] = point_metrics(head, out, H, Y, CARE, torch.nonzero(rows).squeeze(1))
            log(f"  val {name}: precision {r[name][0]:.3f} recall {r[name][1]:.3f}\n")
        return r

    result = {"before": val_metrics() if first_val < n else {}, "loss": []}
    gen = torch.Generator().manual_seed(seed)
    train_rows = torch.nonzero(~VAL).squeeze(1)
    bs = min(batch, len(train_rows))
    steps_per_epoch = max(1, len(train_rows) // bs)
    params = list(head.parameters()) + list(out.parameters())
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        opt = torch.optim.AdamW(params, lr=lr, weight_decay=0.01)
        sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr, total_steps=epochs * steps_per_epoch,
                                                    pct_start=0.05)
        for ep in range(epochs):
            perm = train_rows[torch.randperm(len(train_rows), generator=gen)]
            total = 0.0
            for k in range(steps_per_epoch):
                j = perm[k * bs:(k + 1) * bs]
                lg = _head_logits(head, out, H[j].float())
                y, care, lm = Y[j], CARE[j], LOCM[j]
                l_fg = (sigmoid_focal_loss(lg[:, 0], y, alpha=alpha) * care).sum() / max(float((y * care).sum()), 1.0)
                bce = F.binary_cross_entropy_with_logits(lg[:, 1:], LOC[j], reduction="none").sum(dim=1)
                loss = l_fg + (bce * lm).sum() / (3.0 * max(float(lm.sum()), 1.0))
                if not torch.isfinite(loss):
                    raise FloatingPointError(f"ds3d.htx.finetune_part: non-finite loss in epoch {ep}")
                opt.zero_grad()
                loss.backward()
                opt.step()
                sched.step()
                total += float(loss)
            result["loss"].append(total / steps_per_epoch)
            log(f"epoch {ep + 1}/{epochs}: loss {result['loss'][-1]:.4f} ({time.time() - t0:.0f} s)\n")
    result["after"] = val_metrics() if first_val < n else {}
    return result


def main(argv=None, stream=sys.stderr):
    p = argparse.ArgumentParser(prog="python3 -m ds3d.htx.finetune_part", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", required=True, help="weights file to start from (.safetensors)")
    p.add_argument("--data", required=True, help="folder of training .npz shards (ds3d.htx.make_dataset)")
    p.add_argument("--out", required=True, help="weights file to write (may be --model)")
    p.add_argument("--epochs", type=int, default=6)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--alpha", type=float, default=0.5, help="focal-loss weight of the human class, (0, 1)")
    p.add_argument("--batch", type=int, default=16384, help="points per step")
    p.add_argument("--val-fraction", type=float, default=0.1)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=2, help="torch intra-op threads")
    a = p.parse_args(argv)
    if a.epochs < 1 or a.batch < 1 or a.threads < 1:
        p.error(f"--epochs, --batch and --threads must be >= 1 (got {a.epochs}, {a.batch}, {a.threads})")
    if not a.lr > 0 or not 0 < a.alpha < 1 or not 0 <= a.val_fraction < 1:
        p.error(f"need --lr > 0, 0 < --alpha < 1, 0 <= --val-fraction < 1 (got {a.lr}, {a.alpha}, "
                f"{a.val_fraction})")
    from .evaluate import _model_from_safetensors
    from .weights import export

    torch.set_num_threads(a.threads)
    model = _model_from_safetensors(a.model)
    before = copy.deepcopy(model.state_dict())
    result = finetune_part(model, HtxDataset(a.data), a.epochs, a.lr, a.alpha, a.batch, a.val_fraction,
                           a.seed, stream)
    changed = [k for k, v in model.state_dict().items() if not torch.equal(v, before[k])]
    if any(not k.startswith(("part_head.", "part_out.")) for k in changed):
        raise RuntimeError(f"ds3d.htx.finetune_part: tensors outside the part head changed: {changed}")
    pathlib.Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    export(model, a.out)
    stream.write(f"wrote {a.out}\n")
    return result


if __name__ == "__main__":
    main()
