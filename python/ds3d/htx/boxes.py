# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Box conventions of spec §2 (SUN RGB-D upright depth frame: X right, Y forward, Z up).

A box is (cx, cy, cz, dx, dy, dz, theta): full sizes (length along the heading arrow, width,
height) and heading theta measured from +X towards -Y. World -> local: apply Rz(+theta).
All functions are numpy float64 unless stated.
"""
import math

import numpy as np


def to_local(points, box):
    """Points [n, 3] in the frame of ``box`` (7,): local = Rz(+theta) (p - c)."""
    p = np.asarray(points, dtype=np.float64) - np.asarray(box[:3], dtype=np.float64)
    c, s = math.cos(float(box[6])), math.sin(float(box[6]))
    return np.stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1], p[:, 2]], axis=1)


def points_in_box(points, box, enlarge=0.0):
    """Boolean [n]: inside ``box`` with every full size grown by ``enlarge`` metres. Strict in
    x and y, inclusive in z (OpenPCDet's check_pt_in_box3d; the C++ box3.hpp is identical)."""
    loc = to_local(points, box)
    hx = (float(box[3]) + enlarge) / 2.0
    hy = (float(box[4]) + enlarge) / 2.0
    hz = (float(box[5]) + enlarge) / 2.0
    return (np.abs(loc[:, 0]) < hx) & (np.abs(loc[:, 1]) < hy) & (np.abs(loc[:, 2]) <= hz)


def corners(box):
    """8 corners [8, 3]: centre + Rz(-theta) (+-dx/2, +-dy/2, +-dz/2)."""
    cx, cy, cz, dx, dy, dz, th = (float(v) for v in box[:7])
    sx = np.array([1, 1, -1, -1, 1, 1, -1, -1]) * dx / 2
    sy = np.array([1, -1, -1, 1, 1, -1, -1, 1]) * dy / 2
    sz = np.array([1, 1, 1, 1, -1, -1, -1, -1]) * dz / 2
    c, s = math.cos(th), math.sin(th)  # Rz(-theta) = [[c, s], [-s, c]]
    return np.stack([cx + c * sx + s * sy, cy - s * sx + c * sy, cz + sz], axis=1)


def aabb(boxes):
    """Axis-aligned hull of each box's corners: [m, 6] (xmin, ymin, zmin, xmax, ymax, zmax)."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 7)
    c, s = np.abs(np.cos(b[:, 6])), np.abs(np.sin(b[:, 6]))
    hx = (c * b[:, 3] + s * b[:, 4]) / 2
    hy = (s * b[:, 3] + c * b[:, 4]) / 2
    hz = b[:, 5] / 2
    h = np.stack([hx, hy, hz], axis=1)
    return np.concatenate([b[:, :3] - h, b[:, :3] + h], axis=1)


def encode_angle(theta, num_bins=12):
    """3DETR angle target: (bin, residual normalised by pi/num_bins), residual in [-1, 1)."""
    theta = np.asarray(theta, dtype=np.float64)
    bin_width = 2 * math.pi / num_bins
    shifted = np.mod(np.mod(theta, 2 * math.pi) + bin_width / 2, 2 * math.pi)
    b = np.floor(shifted / bin_width).astype(np.int64) % num_bins
    res = shifted - (b * bin_width + bin_width / 2)
    return b, res / (bin_width / 2)


def decode_angle(bin_index, residual_normalized, num_bins=12):
    """Inverse of encode_angle: theta = b * 2pi/num_bins + r * pi/num_bins, wrapped to (-pi, pi]."""
    th = np.asarray(bin_index) * (2 * math.pi / num_bins) + np.asarray(residual_normalized) * (math.pi / num_bins)
    return np.where(th > math.pi, th - 2 * math.pi, th)


def _footprint(b):
    """[m, 4, 2] footprint polygons (counter-clockwise) of boxes [m, 7]."""
    sx = np.array([1, -1, -1, 1])[None, :] * b[:, 3:4] / 2
    sy = np.array([1, 1, -1, -1])[None, :] * b[:, 4:5] / 2
    c, s = np.cos(b[:, 6:7]), np.sin(b[:, 6:7])
    x = b[:, 0:1] + c * sx + s * sy
    y = b[:, 1:2] - s * sx + c * sy
    return np.stack([x, y], axis=-1)


def _inside_convex(pts, poly):
    """pts [p, k, 2] inside convex polygons poly [p, 4, 2] (either orientation), with tolerance."""
    a = poly[:, None, :, :]
    e = np.roll(poly, -1, axis=1)[:, None, :, :] - a
    r = pts[:, :, None, :] - a
    cross = e[..., 0] * r[..., 1] - e[..., 1] * r[..., 0]  # [p, k, 4]
    tol = 1e-9
    return np.all(cross >= -tol, axis=2) | np.all(cross <= tol, axis=2)


def footprint_intersection_area(b1, b2):
    """Area of the intersection of the rotated footprints of paired boxes b1[i], b2[i] ([p, 7])."""
    p1, p2 = _footprint(b1), _footprint(b2)
    n = p1.shape[0]
    # candidate vertices: corners inside the other polygon and edge-edge crossings
    a1, d1 = p1[:, :, None, :], (np.roll(p1, -1, axis=1) - p1)[:, :, None, :]
    a2, d2 = p2[:, None, :, :], (np.roll(p2, -1, axis=1) - p2)[:, None, :, :]
    den = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]  # [p, 4, 4]
    w = a2 - a1
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * d2[..., 1] - w[..., 1] * d2[..., 0]) / den
        u = (w[..., 0] * d1[..., 1] - w[..., 1] * d1[..., 0]) / den
    ok_x = (np.abs(den) > 1e-12) & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)
    cross_pts = (a1 + np.where(ok_x, t, 0.0)[..., None] * d1).reshape(n, 16, 2)
    pts = np.concatenate([p1, p2, cross_pts], axis=1)  # [p, 24, 2]
    valid = np.concatenate([_inside_convex(p1, p2), _inside_convex(p2, p1), ok_x.reshape(n, 16)], axis=1)
    cnt = valid.sum(axis=1)
    cen = np.where(cnt[:, None] > 0, (pts * valid[..., None]).sum(axis=1) / np.maximum(cnt, 1)[:, None], 0.0)
    ang = np.arctan2(pts[..., 1] - cen[:, 1:2], pts[..., 0] - cen[:, 0:1])
    ang = np.where(valid, ang, np.inf)
    order = np.argsort(ang, axis=1)
    sp = np.take_along_axis(pts, order[..., None], axis=1)
    sv = np.take_along_axis(valid, order, axis=1)
    first = sp[:, :1, :]
    sp = np.where(sv[..., None], sp, first)  # trailing invalid points repeat the first: zero area
    nx = np.roll(sp, -1, axis=1)
    area = 0.5 * np.abs((sp[..., 0] * nx[..., 1] - nx[..., 0] * sp[..., 1]).sum(axis=1))
    return np.where(cnt >= 3, area, 0.0)


def generalized_iou_3d(b1, b2):
    """GIoU matrix [m1, m2] between boxes b1 [m1, 7] and b2 [m2, 7] (3DETR's definition: rotated
    footprint intersection x vertical overlap; enclosing = AABB of both corner sets)."""
    b1 = np.asarray(b1, dtype=np.float64).reshape(-1, 7)
    b2 = np.asarray(b2, dtype=np.float64).reshape(-1, 7)
    m1, m2 = len(b1), len(b2)
    if m1 == 0 or m2 == 0:
        return np.zeros((m1, m2))
    i1, i2 = np.repeat(np.arange(m1), m2), np.tile(np.arange(m2), m1)
    p, q = b1[i1], b2[i2]
    area = footprint_intersection_area(p, q)
    zlo = np.maximum(p[:, 2] - p[:, 5] / 2, q[:, 2] - q[:, 5] / 2)
    zhi = np.minimum(p[:, 2] + p[:, 5] / 2, q[:, 2] + q[:, 5] / 2)
    inter = area * np.maximum(zhi - zlo, 0.0)
    v1, v2 = np.prod(p[:, 3:6], axis=1), np.prod(q[:, 3:6], axis=1)
    union = v1 + v2 - inter
    a, b = aabb(p), aabb(q)
    enc = np.prod(np.maximum(a[:, 3:], b[:, 3:]) - np.minimum(a[:, :3], b[:, :3]), axis=1)
    iou = inter / np.maximum(union, 1e-12)
    giou = iou - (enc - union) / np.maximum(enc, 1e-12)
    return giou.reshape(m1, m2)


def aabb_iou(a, b):
    """IoU of two axis-aligned boxes (xmin, ymin, zmin, xmax, ymax, zmax)."""
    lo = np.maximum(a[:3], b[:3])
    hi = np.minimum(a[3:], b[3:])
    inter = float(np.prod(np.maximum(hi - lo, 0.0)))
    va, vb = float(np.prod(a[3:] - a[:3])), float(np.prod(b[3:] - b[:3]))
    union = va + vb - inter
    return inter / union if union > 0 else 0.0
