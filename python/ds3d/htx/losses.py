# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Losses: 3DETR set loss with Hungarian matching (seed eq. 1; Misra et al. 2021, criterion.py)
and Part-A2's part-location loss (seed eq. 3; Shi et al. 2020), spec §4 and §5."""
import numpy as np
import torch
import torch.nn.functional as F
from scipy.optimize import linear_sum_assignment

from .boxes import generalized_iou_3d
from .targets import box_targets, part_targets

SUNRGBD_WEIGHTS = {
    "match_cls": 1.0, "match_obj": 5.0, "match_center": 5.0, "match_giou": 3.0,
    "sem_cls": 1.0, "center": 5.0, "size": 1.0, "angle_cls": 0.1, "angle_reg": 0.5, "giou": 0.0,
    "background_weight": 0.1, "part_fg": 1.0, "part_loc": 1.0,
}


@torch.no_grad()
def hungarian_match(pred, tgt, weights=SUNRGBD_WEIGHTS):
    """Matches queries to GT boxes minimising w_cls(-p[gt class]) + w_obj(-objectness) +
    w_center L1(centre_norm) + w_giou(-GIoU). Returns (query indices, gt indices) as numpy."""
    g = len(tgt["classes"])
    if g == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    prob = pred["sem_cls_prob"].detach().double().numpy()  # [q, K]
    obj = pred["objectness"].detach().double().numpy()
    cn = pred["center_normalized"].detach().double().numpy()
    cost = (-weights["match_cls"] * prob[:, tgt["classes"]]
            - weights["match_obj"] * obj[:, None]
            + weights["match_center"] * np.abs(cn[:, None, :] - tgt["center_normalized"][None]).sum(-1))
    if weights["match_giou"] != 0:
        pb = np.concatenate([pred["center"].detach().double().numpy(), pred["size"].detach().double().numpy(),
                             pred["angle"].detach().double().numpy()[:, None]], axis=1)
        gb = tgt["boxes"]
        if not np.any(gb[:, 6] != 0):  # 3DETR uses axis-aligned footprints without GT rotation
            pb = pb.copy()
            pb[:, 6] = 0.0
        cost = cost - weights["match_giou"] * generalized_iou_3d(pb, gb)
    return linear_sum_assignment(cost)


def huber(x, delta=1.0):
    a = x.abs()
    return torch.where(a < delta, 0.5 * a * a, delta * (a - 0.5 * delta))


def detection_loss(layer_outputs, tgt, weights=SUNRGBD_WEIGHTS):
    """Seed eq. 1 summed over decoder layers (each with its own matching). ``layer_outputs`` is
    the model's ``layers`` list; ``tgt`` from targets.box_targets. Returns (loss, dict of parts)."""
    total = 0.0
    parts = {}
    g = len(tgt["classes"])
    ng = max(g, 1)
    for li, pred in enumerate(layer_outputs):
        qi, gi = hungarian_match(pred, tgt, weights)
        q = pred["sem_cls_logits"].shape[0]
        k = pred["sem_cls_logits"].shape[1] - 1
        cls_t = torch.full((q,), k, dtype=torch.long)
        cls_t[torch.as_tensor(qi, dtype=torch.long)] = torch.as_tensor(tgt["classes"][gi], dtype=torch.long)
        cw = torch.ones(k + 1)
        cw[-1] = weights["background_weight"]
        l_cls = F.cross_entropy(pred["sem_cls_logits"], cls_t, weight=cw)
        if g > 0:
            qi_t, gi_t = torch.as_tensor(qi, dtype=torch.long), torch.as_tensor(gi, dtype=torch.long)
            cn_t = torch.as_tensor(tgt["center_normalized"], dtype=torch.float32)[gi_t]
            sn_t = torch.as_tensor(tgt["size_normalized"], dtype=torch.float32)[gi_t]
            ab_t = torch.as_tensor(tgt["angle_bin"], dtype=torch.long)[gi_t]
            ar_t = torch.as_tensor(tgt["angle_residual_normalized"], dtype=torch.float32)[gi_t]
            l_center = (pred["center_normalized"][qi_t] - cn_t).abs().sum() / ng
            l_size = (pred["size_normalized"][qi_t] - sn_t).abs().sum() / ng
            l_acls = F.cross_entropy(pred["angle_logits"][qi_t], ab_t, reduction="sum") / ng
            res = torch.gather(pred["angle_residual_normalized"][qi_t], 1, ab_t[:, None])[:, 0]
            l_areg = huber(res - ar_t).sum() / ng
        else:
            l_center = l_size = l_acls = l_areg = pred["center_normalized"].sum() * 0.0
        layer_loss = (weights["sem_cls"] * l_cls + weights["center"] * l_center + weights["size"] * l_size
                      + weights["angle_cls"] * l_acls + weights["angle_reg"] * l_areg)
        total = total + layer_loss
        for name, v in (("sem_cls", l_cls), ("center", l_center), ("size", l_size),
                        ("angle_cls", l_acls), ("angle_reg", l_areg)):
            parts[f"{name}_{li}"] = float(v)
    return total, parts


def sigmoid_focal_loss(logits, target, alpha=0.25, gamma=2.0):
    """Per-element sigmoid focal loss (Lin et al. 2017), as in OpenPCDet's point head."""
    p = torch.sigmoid(logits)
    ce = F.binary_cross_entropy_with_logits(logits, target, reduction="none")
    pt = p * target + (1 - p) * (1 - target)
    w = alpha * target + (1 - alpha) * (1 - target)
    return w * (1 - pt) ** gamma * ce


def part_loss(part_logits, label, part_target, weights=SUNRGBD_WEIGHTS, npos=None):
    """Part-A2 point losses (seed eq. 3): foreground focal loss normalised by #positives over
    non-ignored points, plus BCE(sigmoid(part logits), targets) summed over xyz on foreground
    points, divided by 3 max(1, #fg). part_logits [n, 4] (fg, part x, y, z). ``npos``: the
    normaliser max(1, #fg) to use instead (data-parallel training: the global batch's)."""
    label = torch.as_tensor(label)
    tgt = torch.as_tensor(part_target, dtype=torch.float32)
    fg = label > 0
    care = (label >= 0).float()
    npos = max(int(fg.sum()), 1) if npos is None else npos
    l_fg = (sigmoid_focal_loss(part_logits[:, 0], fg.float()) * care).sum() / npos
    bce = F.binary_cross_entropy_with_logits(part_logits[:, 1:], tgt, reduction="none").sum(dim=1)
    l_part = (bce * fg.float()).sum() / (3.0 * npos)
    return weights["part_fg"] * l_fg + weights["part_loc"] * l_part, {"part_fg": float(l_fg), "part_loc": float(l_part)}


def scene_loss(model, xyz, gt_boxes, gt_classes, weights=SUNRGBD_WEIGHTS):
    """Total training loss of one scene (train mode: all decoder layers, part head).
    gt_boxes [g, 7] full sizes (spec §2). Returns (loss tensor, dict of components)."""
    xyz_t = torch.as_tensor(np.asarray(xyz, dtype=np.float32))
    out = model(xyz_t, with_parts=True, all_layers=True)
    tgt = box_targets(gt_boxes, gt_classes, out["scene_min"].numpy(), out["scene_max"].numpy(),
                      model.config["num_angle_bins"])
    det, parts = detection_loss(out["layers"], tgt, weights)
    pt = part_targets(xyz_t.numpy(), gt_boxes)
    pl, pparts = part_loss(out["part_logits"], pt["label"], pt["part"], weights)
    parts.update(pparts)
    return det + pl, parts
