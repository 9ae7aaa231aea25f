# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""PyTorch reference inference with the post-processing that ds3d::SparseDetector::detect()
implements (spec §3.8): empty-box removal, objectness threshold, same-class AABB NMS."""
import numpy as np
import torch

from .boxes import points_in_box
from .nms import nms_3d_same_class

COLUMNS = ("cx", "cy", "cz", "dx", "dy", "dz", "yaw", "score", "class")


def _as_points(points):
    p = np.asarray(points)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"ds3d.htx.reference_detect: points must have shape (n, 3) (got {p.shape})")
    p = p.astype(np.float32)
    if not np.all(np.isfinite(p)):
        row = int(np.argwhere(~np.isfinite(p).all(axis=1))[0, 0])
        raise ValueError(f"ds3d.htx.reference_detect: points row {row} is not finite")
    return p


def postprocess(points, boxes, objectness, class_prob, config):
    """Post-processing of spec §3.8 on per-query proposals, exactly as the C++
    SparseDetector::postprocess: drop boxes holding fewer than min_points_in_box points (keep
    the highest-objectness one if all go), keep objectness > score_threshold, same-class AABB NMS.

    points [n, 3]; boxes [q, 7]; objectness [q]; class_prob [q, K] (float32 values, computed on
    in float64). Returns (kept indices, (M, 9) float32 rows cx..yaw, score, class)."""
    pts = np.asarray(points, dtype=np.float32).astype(np.float64)
    boxes = np.asarray(boxes, dtype=np.float32).astype(np.float64).reshape(-1, 7)
    obj = np.asarray(objectness, dtype=np.float32).astype(np.float64)
    prob = np.asarray(class_prob, dtype=np.float32).astype(np.float64)
    labels = np.argmax(prob, axis=1) if len(prob) else np.zeros(0, np.int64)
    scores = prob[np.arange(len(labels)), labels] * obj
    need = config["min_points_in_box"]
    keep = np.array([int(points_in_box(pts, b).sum()) >= need for b in boxes], dtype=bool)
    if not keep.any() and len(boxes) > 0:
        keep[int(np.argmax(obj))] = True
    keep &= obj > float(np.float32(config["score_threshold"]))
    cand = np.nonzero(keep)[0]
    kept = [int(cand[i]) for i in nms_3d_same_class(boxes[cand], obj[cand], labels[cand],
                                                    float(np.float32(config["nms_iou"])))]
    out = np.zeros((len(kept), 9), dtype=np.float32)
    for r, i in enumerate(kept):
        out[r, :7] = boxes[i]
        out[r, 7] = scores[i]
        out[r, 8] = labels[i]
    return kept, out


@torch.no_grad()
def reference_detect(model, points, return_details=False):
    """Runs ``model`` (eval mode) on points (n, 3) and returns numpy (M, 9) float32 rows
    (cx, cy, cz, dx, dy, dz, yaw, score, class), as ds3d.SparseDetector.detect() does.

    With return_details=True also returns a dict with part_logits (n, 4), centre_indices,
    query_indices and the raw per-query predictions (for parity checks)."""
    p = _as_points(points)
    if len(p) == 0:
        empty = np.zeros((0, 9), dtype=np.float32)
        return (empty, {}) if return_details else empty
    was_training = model.training
    model.eval()
    try:
        res = model(torch.from_numpy(p), with_parts=return_details, all_layers=False)
    finally:
        model.train(was_training)
    last = res["layers"][-1]
    boxes = torch.cat([last["center"], last["size"], last["angle"][:, None]], dim=1).numpy()
    _, out = postprocess(p, boxes, last["objectness"].numpy(), last["sem_cls_prob"].numpy(), model.config)
    if not return_details:
        return out
    details = {
        "part_logits": res["part_logits"].numpy(),
        "centre_indices": res["centre_indices"].numpy(),
        "query_indices": res["query_indices"].numpy(),
        "center": last["center"].numpy(), "size": last["size"].numpy(),
        "angle": last["angle"].numpy(), "objectness": last["objectness"].numpy(),
        "sem_cls_prob": last["sem_cls_prob"].numpy(),
    }
    return out, details
