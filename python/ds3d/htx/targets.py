# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Training targets: Part-A2 intra-object part locations (seed eq. 2 with Part-A2's +0.5) and
3DETR box targets (spec §4, §5). numpy float64; the C++ twin is include/ds3d/part_a2_targets.hpp."""
import numpy as np

from .boxes import encode_angle, to_local, points_in_box


def part_targets(points, boxes, extra_width=0.2):
    """Part-A2 point targets (Shi et al. 2020, OpenPCDet assign_stack_targets).

    points [n, 3], boxes [m, 7] (cx, cy, cz, dx, dy, dz, theta; spec §2). A point inside a box is
    foreground (label 1) and belongs to the first such box; a point inside some box grown by
    ``extra_width`` metres per full size but in none of the boxes is ignored (label -1); others
    are background (0). Part target of a foreground point = local / size + 0.5 in [0, 1]^3
    (0.5 = box centre); zeros elsewhere.

    Returns dict: label int8 [n], box_index int64 [n] (-1 if none), part float32 [n, 3].
    """
    pts = np.asarray(points, dtype=np.float32).astype(np.float64).reshape(-1, 3)
    bx = np.asarray(boxes, dtype=np.float32).astype(np.float64).reshape(-1, 7)
    if not np.all(np.isfinite(pts)) or not np.all(np.isfinite(bx)):
        raise ValueError("ds3d.htx.part_targets: points and boxes must be finite")
    if np.any(bx[:, 3:6] <= 0):
        raise ValueError("ds3d.htx.part_targets: box sizes must be > 0")
    n = len(pts)
    label = np.zeros(n, dtype=np.int8)
    box_index = np.full(n, -1, dtype=np.int64)
    part = np.zeros((n, 3), dtype=np.float64)
    enlarged = np.zeros(n, dtype=bool)
    for k, b in enumerate(bx):
        inside = points_in_box(pts, b) & (box_index < 0)
        enlarged |= points_in_box(pts, b, enlarge=extra_width)
        if inside.any():
            loc = to_local(pts[inside], b)
            part[inside] = loc / b[3:6] + 0.5
            box_index[inside] = k
    label[box_index >= 0] = 1
    label[(box_index < 0) & enlarged] = -1
    return {"label": label, "box_index": box_index, "part": part.astype(np.float32)}


def box_targets(gt_boxes, gt_classes, scene_min, scene_max, num_bins=12):
    """3DETR box targets for one scene: normalised centres and sizes, angle bin + normalised
    residual (spec §4). gt_boxes [g, 7] with full sizes. Returns a dict of numpy arrays."""
    b = np.asarray(gt_boxes, dtype=np.float64).reshape(-1, 7)
    lo, hi = np.asarray(scene_min, np.float64), np.asarray(scene_max, np.float64)
    extent = np.maximum(hi - lo, 1e-6)
    ab, ar = encode_angle(b[:, 6], num_bins)
    return {
        "boxes": b, "classes": np.asarray(gt_classes, dtype=np.int64).reshape(-1),
        "center_normalized": (b[:, :3] - lo) / extent,
        "size_normalized": b[:, 3:6] / extent,
        "angle_bin": ab, "angle_residual_normalized": ar,
    }
