# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Same-class 3-D NMS on axis-aligned hulls (3DETR's nms_3d_faster_samecls, spec §3.8)."""
import numpy as np

from .boxes import aabb, aabb_iou


def nms_3d_same_class(boxes, scores, labels, iou_threshold=0.25):
    """Greedy NMS: visit boxes by decreasing score (stable: lower index first on ties), keep a
    box unless an already kept box of the same label overlaps it with AABB IoU > threshold.
    Returns kept indices in visiting order. boxes [m, 7], scores [m], labels [m]."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 7)
    scores = np.asarray(scores, dtype=np.float64)
    labels = np.asarray(labels)
    hull = aabb(boxes)
    order = sorted(range(len(boxes)), key=lambda i: (-scores[i], i))
    keep = []
    for i in order:
        if all(labels[j] != labels[i] or aabb_iou(hull[i], hull[j]) <= iou_threshold for j in keep):
            keep.append(i)
    return keep
