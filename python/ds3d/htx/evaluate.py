# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Evaluation of a trained HTx-lite model (docs/htx_training.md).

    python3 -m ds3d.htx.evaluate synthetic --model RUN/checkpoint.pt --data DIR/test [--json out.json]
    python3 -m ds3d.htx.evaluate tum --model models/htx_lite_fast.safetensors --data ../shared/data/tum_fr3_walking_xyz_3frames
    python3 -m ds3d.htx.evaluate overlays --model ... --data ../shared/data/bonn_crowd_first300 --out DIR --frames 0,60,120

- synthetic: person AP@0.25 and AP@0.5 (VOC area under the interpolated precision/recall curve,
  3DETR's eval_det; rotated-box 3-D IoU = footprint intersection x vertical overlap / union),
  recall of all and of partly visible humanoids (truncated by the image border or >= 10% of the
  projected box covered by nearer objects) at the deployment threshold and at IoU 0.25.
- tum: on real frames with person masks, the share of masked person pixels inside the predicted
  boxes projected into the image (hull rectangle of the 8 projected corners) and, in 3-D, the
  share of masked pixels with depth whose point lies in a predicted box grown by 0.2 m.
- overlays: predicted boxes drawn on the RGB images of a TUM/Bonn folder.

Detection runs through the C++ ``ds3d.SparseDetector`` when the extension has it (the path
``ds3d-slam --dynamic htx`` uses), else through ``ds3d.htx.reference_detect``; they agree
(docs/htx.md). Input per frame: ``ds3d.preprocess`` (inference defaults) -> gravity_rotation ->
at most 4,096 points, exactly as in ds3d.htx.data.
"""
import argparse
import json
import math
import pathlib
import sys
import tempfile

import numpy as np

from . import data
from .boxes import corners, footprint_intersection_area, points_in_box

PARTLY_OCCLUDED = 0.1  # occluded_fraction above which a humanoid counts as partly visible


def iou_3d(box, boxes):
    """Rotated 3-D IoU of one box (7,) with boxes [m, 7] (spec §2 convention)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 7)
    if len(b) == 0:
        return np.zeros(0)
    a = np.repeat(np.asarray(box, np.float64).reshape(1, 7), len(b), axis=0)
    area = footprint_intersection_area(a, b)
    zlo = np.maximum(a[:, 2] - a[:, 5] / 2, b[:, 2] - b[:, 5] / 2)
    zhi = np.minimum(a[:, 2] + a[:, 5] / 2, b[:, 2] + b[:, 5] / 2)
    inter = area * np.maximum(zhi - zlo, 0.0)
    union = np.prod(a[:, 3:6], axis=1) + np.prod(b[:, 3:6], axis=1) - inter
    return inter / np.maximum(union, 1e-12)


def voc_ap(recall, precision):
    """Area under the precision envelope (VOC 2010+, as 3DETR's eval_det.voc_ap without 07)."""
    mrec = np.concatenate([[0.0], recall, [1.0]])
    mpre = np.concatenate([[0.0], precision, [0.0]])
    for i in range(len(mpre) - 1, 0, -1):
        mpre[i - 1] = max(mpre[i - 1], mpre[i])
    i = np.nonzero(mrec[1:] != mrec[:-1])[0]
    return float(np.sum((mrec[i + 1] - mrec[i]) * mpre[i + 1]))


def average_precision(dets, gts, iou_threshold):
    """dets: list per frame of (M, 9) rows (score in column 7); gts: list per frame of [g, 7].
    Greedy by decreasing score over the whole set, each GT matched once (VOC). Returns
    (AP, recall at the end of the list, number of GT)."""
    rows = [(float(d[7]), f, k) for f, dd in enumerate(dets) for k, d in enumerate(dd)]
    rows.sort(key=lambda r: -r[0])
    npos = sum(len(g) for g in gts)
    used = [np.zeros(len(g), bool) for g in gts]
    tp = np.zeros(len(rows))
    for i, (_, f, k) in enumerate(rows):
        if len(gts[f]) == 0:
            continue
        ious = iou_3d(dets[f][k][:7], gts[f])
        j = int(np.argmax(ious))
        if ious[j] >= iou_threshold and not used[f][j]:
            used[f][j] = True
            tp[i] = 1
    if npos == 0:
        return float("nan"), float("nan"), 0
    ctp = np.cumsum(tp)
    rec = ctp / npos
    prec = ctp / np.maximum(np.arange(1, len(rows) + 1), 1)
    return voc_ap(rec, prec), float(rec[-1]) if len(rec) else 0.0, npos


def matched(dets, gt, iou_threshold):
    """Boolean [g]: GT boxes matched (greedy by score, once each) by detections (M, 9)."""
    used = np.zeros(len(gt), bool)
    for d in sorted(dets, key=lambda r: -float(r[7])):
        if len(gt) == 0:
            break
        ious = np.where(used, -1.0, iou_3d(d[:7], gt))
        j = int(np.argmax(ious))
        if ious[j] >= iou_threshold:
            used[j] = True
    return used


class Detector:
    """Runs a model file (checkpoint .pt or weights .safetensors) on upright clouds; ``detect``
    returns (M, 9) rows with every box whose objectness exceeds ``score_threshold``."""

    def __init__(self, path, score_threshold=0.05, backend="auto"):
        import torch

        from .model import HTx
        from .weights import export
        from .train import load_checkpoint_model

        path = pathlib.Path(path)
        if path.suffix == ".pt":
            self.model = load_checkpoint_model(path)
        else:
            self.model = _model_from_safetensors(path)
        self.deploy_threshold = float(self.model.config["score_threshold"])
        self.model.config["score_threshold"] = float(score_threshold)
        self.cpp = None
        if backend in ("auto", "cpp"):
            try:
                import ds3d
                tmp = tempfile.NamedTemporaryFile(suffix=".safetensors", delete=False)
                tmp.close()
                export(self.model, tmp.name)
                self.cpp = ds3d.SparseDetector.load(tmp.name)
                pathlib.Path(tmp.name).unlink()
            except (ImportError, AttributeError):
                if backend == "cpp":
                    raise
        self.backend = "cpp" if self.cpp is not None else "torch"
        torch.set_num_threads(1)
        del HTx

    def detect(self, points):
        if len(points) == 0:
            return np.zeros((0, 9), np.float32)
        if self.cpp is not None:
            return np.asarray(self.cpp.detect(np.ascontiguousarray(points, np.float32)))
        from .detect import reference_detect
        return reference_detect(self.model, points)


def _exported_name(key):
    """Weight-file name (weights.folded_tensors) of a model state_dict module path."""
    import re

    rules = [(r"^pre_encoder\.(\d+)", r"pre_encoder.mlp.\1"), (r"^encoder\.(\d+)", r"encoder.layers.\1"),
             (r"^decoder\.(\d+)", r"decoder.layers.\1"), (r"^decoder_norm", "decoder.norm"),
             (r"^gauss_B$", "pos_embedding.gauss_B"), (r"^mlp_heads\.(\w+)\.layers\.(\d+)", r"mlp_heads.\1.\2"),
             (r"^mlp_heads\.(\w+)\.out", r"mlp_heads.\1.2"), (r"^part_out", "part_head.1")]
    for pat, rep in rules:
        key = re.sub(pat, rep, key)
    return key


def _model_from_safetensors(path):
    """An HTx (eval mode) from an exported weights file. BatchNorm was folded at export: each
    ConvBNReLU gets the folded weight in its linear layer and an identity BatchNorm carrying the
    folded bias; inference is then identical to the exported network."""
    import torch

    from .model import HTx
    from .weights import read_safetensors

    tensors, meta = read_safetensors(path)
    model = HTx(json.loads(meta["config"])).eval()
    sd = model.state_dict()
    new = {}
    for name, m in model.named_modules():
        if type(m).__name__ == "ConvBNReLU":
            base = _exported_name(name)
            w = tensors[f"{base}.weight"]
            new[f"{name}.linear.weight"] = w
            new[f"{name}.bn.weight"] = np.ones(w.shape[0], np.float32)
            new[f"{name}.bn.bias"] = tensors[f"{base}.bias"]
            new[f"{name}.bn.running_mean"] = np.zeros(w.shape[0], np.float32)
            new[f"{name}.bn.running_var"] = np.full(w.shape[0], 1.0 - m.bn.eps, np.float32)
    for k in sd:
        if k in new:
            continue
        if k.endswith("num_batches_tracked"):
            new[k] = sd[k].numpy()
            continue
        src = tensors.get(_exported_name(k))
        if src is None:
            raise RuntimeError(f"ds3d.htx.evaluate: tensor {_exported_name(k)!r} missing from {path}")
        new[k] = src.reshape(tuple(sd[k].shape))
    model.load_state_dict({k: torch.as_tensor(np.asarray(v)) for k, v in new.items()})
    return model


def evaluate_synthetic(det, ds, deploy_threshold, log=None):
    """AP and recalls on a HtxDataset. Returns a dict of metrics."""
    dets, gts, metas = [], [], []
    for i in range(len(ds)):
        s = ds[i]
        dets.append(det.detect(s["points"]))
        gts.append(s["boxes"].astype(np.float64))
        metas.append(s["box_meta"])
        if log and i % 50 == 0:
            log(f"synthetic {i}/{len(ds)}")
    out = {"frames": len(ds), "gt_boxes": int(sum(len(g) for g in gts))}
    for thr in (0.25, 0.5):
        ap, rmax, npos = average_precision(dets, gts, thr)
        out[f"AP{int(thr * 100)}"] = ap
        out[f"max_recall{int(thr * 100)}"] = rmax
    kept = [d[d[:, 7] >= deploy_threshold] if len(d) else d for d in dets]
    # objectness is what the threshold acts on; the score column = p[class] * objectness (K = 1: equal
    # up to the background share), so thresholding the score here is the deployment filter
    for name, pick in (("all", lambda m: np.ones(len(m), bool)),
                       ("partly_visible", lambda m: (m[:, 3] > 0) | (m[:, 4] >= PARTLY_OCCLUDED)),
                       ("fully_visible", lambda m: (m[:, 3] == 0) & (m[:, 4] < PARTLY_OCCLUDED)),
                       ("sitting", lambda m: m[:, 2] > 0),
                       ("taller_than_train", lambda m: (m[:, 5] > data.TALL) & (m[:, 2] == 0))):
        hit25, hitall, n = 0, 0, 0
        for d, dall, g, m in zip(kept, dets, gts, metas):
            sel = pick(m) if len(m) else np.zeros(0, bool)
            n += int(sel.sum())
            hit25 += int(matched(d, g, 0.25)[sel].sum())
            hitall += int(matched(dall, g, 0.25)[sel].sum())
        out[f"recall25_{name}"] = hit25 / n if n else None  # no box of this kind: undefined
        out[f"recall25_any_score_{name}"] = hitall / n if n else None
        out[f"n_{name}"] = n
    fp = sum(int((~_tp_mask(d, g, 0.25)).sum()) for d, g in zip(kept, gts))
    out["false_positives_per_frame"] = fp / max(len(ds), 1)
    out["deploy_threshold"] = deploy_threshold
    return out


def _tp_mask(dets, gt, thr):
    """Boolean [M]: detection is a true positive (greedy by score, each GT once)."""
    used = np.zeros(len(gt), bool)
    tp = np.zeros(len(dets), bool)
    for k in np.argsort(-dets[:, 7]) if len(dets) else []:
        if len(gt) == 0:
            break
        ious = np.where(used, -1.0, iou_3d(dets[k, :7], gt))
        j = int(np.argmax(ious))
        if ious[j] >= thr:
            used[j] = True
            tp[k] = True
    return tp


def choose_threshold(det, ds):
    """Deployment objectness threshold maximising F1 at IoU 0.25 on a (validation) dataset."""
    dets = [det.detect(ds[i]["points"]) for i in range(len(ds))]
    gts = [ds[i]["boxes"] for i in range(len(ds))]
    best = (0.0, 0.5)
    for thr in np.arange(0.05, 0.96, 0.05):
        tp = fp = 0
        for d, g in zip(dets, gts):
            k = d[d[:, 7] >= thr] if len(d) else d
            m = _tp_mask(k, g, 0.25)
            tp += int(m.sum())
            fp += int((~m).sum())
        npos = sum(len(g) for g in gts)
        f1 = 2 * tp / max(2 * tp + fp + (npos - tp), 1)
        if f1 > best[0]:
            best = (f1, float(thr))
    return best[1], best[0]


def upright_input(depth, camera, prev_up=None, rng_seed=0):
    """Real-frame detector input exactly as ds3d.htx.data: (points [n, 3] upright, R_up_cam,
    PreprocessResult, kept row indices into r.points)."""
    import ds3d

    r = ds3d.preprocess(depth, camera["fx"], camera["fy"], camera["cx"], camera["cy"],
                        depth_scale=camera["depth_scale"], **data.PREPROCESS)
    pts = np.asarray(r.points, np.float32)
    if r.ground_found:
        R = data.gravity_rotation(r.ground_plane)
    else:
        R = data.gravity_rotation(None, prev_up if prev_up is not None else (0.0, -1.0, 0.0))
    keep = np.arange(len(pts))
    if len(pts) > data.MAX_POINTS:
        keep = np.sort(np.random.default_rng(rng_seed).choice(len(pts), data.MAX_POINTS, replace=False))
    return (pts[keep].astype(np.float64) @ R.T).astype(np.float32), R, r, keep


def box_rects(boxes, R, camera, width, height):
    """Image rectangles (u0, v0, u1, v1), clipped, of the projected hulls of upright boxes."""
    out = []
    for b in boxes:
        u, v, z = data.project_box(b[:7], R, camera)
        if np.all(z <= 0.05):
            continue
        u, v = u[z > 0.05], v[z > 0.05]
        out.append((max(0, int(u.min())), max(0, int(v.min())), min(width - 1, int(math.ceil(u.max()))),
                    min(height - 1, int(math.ceil(v.max())))))
    return out


def _no_nan(x):
    """`x` with every non-finite float replaced by None (JSON null): reports never carry NaN."""
    if isinstance(x, dict):
        return {k: _no_nan(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_no_nan(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _read_png16(path):
    from PIL import Image
    return np.asarray(Image.open(path)).astype(np.uint16)


def evaluate_tum_masks(det, folder, camera_preset="tum3"):
    """Share of masked person pixels inside predicted boxes on frames with depth and a mask
    (DynaSLAM's mask images from its repository: value 0 marks a person, 1 the static scene).
    A share whose denominator is empty (no masked pixel, no masked pixel with depth, no box) is
    None (JSON null), never NaN."""
    import ds3d
    from PIL import Image

    folder = pathlib.Path(folder)
    camera = ds3d.camera_preset(camera_preset)
    masks = sorted((folder / "mask").glob("*.png"))
    depths = sorted((folder / "depth").glob("*.png"))
    rows = []
    for dp in depths:
        t = float(dp.stem)
        mp = min(masks, key=lambda m: abs(float(m.stem) - t))
        if abs(float(mp.stem) - t) > 0.02:
            continue
        depth = _read_png16(dp)
        mask = np.asarray(Image.open(mp).convert("L")) == 0  # DynaSLAM's masks: 0 = person, 1 = static
        pts, R, _, _ = upright_input(depth, camera)
        boxes = det.detect(pts)
        h, w = depth.shape
        inside2d = np.zeros((h, w), bool)
        for u0, v0, u1, v1 in box_rects(boxes, R, camera, w, h):
            inside2d[v0:v1 + 1, u0:u1 + 1] = True
        # 3-D: masked pixels with depth, back-projected, inside a box grown by 0.2 m
        vv, uu = np.nonzero(mask & (depth > 0))
        z = depth[vv, uu] / camera["depth_scale"]
        pc = np.stack([(uu - camera["cx"]) * z / camera["fx"], (vv - camera["cy"]) * z / camera["fy"], z], 1)
        pu = pc @ R.T
        in3d = np.zeros(len(pu), bool)
        for b in boxes:
            in3d |= points_in_box(pu, b[:7], enlarge=0.2)
        rows.append({"frame": dp.name, "mask_pixels": int(mask.sum()), "boxes": len(boxes),
                     "scores": [round(float(s), 3) for s in boxes[:, 7]],
                     "share_mask_in_projected_boxes": float(inside2d[mask].mean()) if mask.any() else None,
                     "share_mask_points_in_boxes_3d": float(in3d.mean()) if len(in3d) else None,
                     "share_box_area_on_mask": float(mask[inside2d].mean()) if inside2d.any() else None})
    return rows


def draw_overlays(det, folder, out_dir, frames):
    """Draws predicted boxes (projected 3-D edges, score) and the detector input points on the
    RGB images of a TUM-layout folder; returns one dict per frame."""
    import ds3d
    from PIL import Image, ImageDraw

    dset = ds3d.RgbdDataset(str(folder))
    camera = dset.camera
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    edges = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
    rows = []
    prev_up = None
    for i in frames:
        f = dset.frame(int(i))
        pts, R, r, _ = upright_input(f["depth"], camera, prev_up)
        prev_up = R.T @ np.array([0, 0, 1.0])
        boxes = det.detect(pts)
        img = Image.fromarray(f["rgb"][:, :, ::-1].copy())
        dr = ImageDraw.Draw(img)
        pc = pts.astype(np.float64) @ R  # back to the camera
        ok = pc[:, 2] > 0.05
        u = camera["fx"] * pc[ok, 0] / pc[ok, 2] + camera["cx"]
        v = camera["fy"] * pc[ok, 1] / pc[ok, 2] + camera["cy"]
        for a, b in zip(u, v):
            dr.point((float(a), float(b)), fill=(0, 255, 255))
        for b in boxes:
            bu, bv, bz = data.project_box(b[:7], R, camera)
            if np.any(bz <= 0.05):
                continue
            for a, c in edges:
                dr.line([(bu[a], bv[a]), (bu[c], bv[c])], fill=(255, 40, 40), width=2)
            dr.text((float(bu.min()), float(bv.min()) - 12), f"{b[7]:.2f}", fill=(255, 255, 0))
        dr.text((5, 5), f"frame {i}: {len(boxes)} boxes, {len(pts)} pts, floor {'yes' if r.ground_found else 'no'}",
                fill=(255, 255, 255))
        path = out / f"overlay_{int(i):04d}.png"
        img.save(path)
        rows.append({"frame": int(i), "boxes": len(boxes), "points": len(pts), "ground_found": bool(r.ground_found),
                     "scores": [round(float(s), 3) for s in boxes[:, 7]],
                     "box_sizes": [[round(float(x), 2) for x in b[3:6]] for b in boxes], "image": str(path)})
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mode", choices=("synthetic", "threshold", "tum", "overlays"))
    p.add_argument("--model", required=True, help="checkpoint.pt or weights .safetensors")
    p.add_argument("--data", required=True, help="shard folder (synthetic, threshold) or TUM-layout folder")
    p.add_argument("--threshold", type=float, default=None,
                   help="deployment objectness threshold (default: the model's score_threshold)")
    p.add_argument("--backend", default="auto", choices=("auto", "cpp", "torch"))
    p.add_argument("--frames", default="0,50,100,150,200,250", help="overlays: frame indices")
    p.add_argument("--out", default="htx_overlays", help="overlays: output folder")
    p.add_argument("--json", default=None, help="also write the result here")
    a = p.parse_args(argv)
    if a.threshold is not None and not 0 <= a.threshold < 1:
        p.error(f"--threshold must be in [0, 1) (got {a.threshold})")
    min_thr = 0.05 if a.threshold is None else min(0.05, a.threshold)
    det = Detector(a.model, score_threshold=min_thr if a.mode in ("synthetic", "threshold") else
                   (a.threshold if a.threshold is not None else None) or 0.0, backend=a.backend)
    if a.mode in ("tum", "overlays") and a.threshold is None:
        det = Detector(a.model, score_threshold=det.deploy_threshold, backend=a.backend)
    deploy = det.deploy_threshold if a.threshold is None else a.threshold
    log = lambda m: sys.stderr.write(m + "\n")  # noqa: E731
    if a.mode == "synthetic":
        res = evaluate_synthetic(det, data.HtxDataset(a.data), deploy, log)
    elif a.mode == "threshold":
        thr, f1 = choose_threshold(det, data.HtxDataset(a.data))
        res = {"threshold": thr, "f1": f1}
    elif a.mode == "tum":
        res = evaluate_tum_masks(det, a.data)
    else:
        res = draw_overlays(det, a.data, a.out, [int(x) for x in a.frames.split(",") if x.strip()])
    res = {"mode": a.mode, "backend": det.backend, "model": str(a.model), "result": res}
    text = json.dumps(_no_nan(res), indent=1, allow_nan=False)
    print(text)
    if a.json:
        pathlib.Path(a.json).write_text(text)


if __name__ == "__main__":
    main()
