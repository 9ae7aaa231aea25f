# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""SUN RGB-D scenes in the VoteNet / 3DETR layout (spec §8).

A split folder (e.g. sunrgbd_pc_bbox_votes_50k_v1_train) holds, per scan NNNNNN:
``NNNNNN_pc.npz`` (key ``pc``, float64 (N, 6): x, y, z upright depth frame, r, g, b in [0, 1])
and ``NNNNNN_bbox.npy`` (float64 (K, 8): cx, cy, cz, half sizes l, w, h, heading, class).
Boxes are returned with full sizes (2 x the stored half sizes), heading unchanged (spec §2).
"""
import os
import re

import numpy as np

SUNRGBD_CLASSES = ("bed", "table", "sofa", "chair", "toilet", "desk", "dresser", "night_stand",
                   "bookshelf", "bathtub")


def load_sunrgbd_scene(folder, scan):
    """Loads scan ``scan`` (int or 6-character id) from ``folder``.

    Returns dict: points float32 (N, 3), colors float32 (N, 3) (empty (N, 0) if absent),
    boxes float64 (K, 7) with full sizes, classes int64 (K,). Raises RuntimeError naming the file
    on a missing or malformed file."""
    sid = f"{int(scan):06d}" if not isinstance(scan, str) else scan
    pc_path = os.path.join(folder, f"{sid}_pc.npz")
    bb_path = os.path.join(folder, f"{sid}_bbox.npy")
    try:
        with np.load(pc_path) as z:
            pc = np.asarray(z["pc"], dtype=np.float64)
        bb = np.asarray(np.load(bb_path), dtype=np.float64)
    except (OSError, KeyError, ValueError) as e:
        raise RuntimeError(f"ds3d.htx.load_sunrgbd_scene: cannot read scan {sid} in {folder}: {e}") from e
    if pc.ndim != 2 or pc.shape[1] < 3:
        raise RuntimeError(f"ds3d.htx.load_sunrgbd_scene: {pc_path}: pc must be (N, >=3) (got {pc.shape})")
    if bb.size == 0:
        bb = np.zeros((0, 8))
    if bb.ndim != 2 or bb.shape[1] != 8:
        raise RuntimeError(f"ds3d.htx.load_sunrgbd_scene: {bb_path}: bbox must be (K, 8) (got {bb.shape})")
    if not (np.all(np.isfinite(pc[:, :3])) and np.all(np.isfinite(bb))):
        raise RuntimeError(f"ds3d.htx.load_sunrgbd_scene: scan {sid}: non-finite values")
    boxes = np.concatenate([bb[:, 0:3], 2.0 * bb[:, 3:6], bb[:, 6:7]], axis=1)
    return {"points": pc[:, :3].astype(np.float32), "colors": pc[:, 3:6].astype(np.float32),
            "boxes": boxes, "classes": bb[:, 7].astype(np.int64)}


class SunRgbdDataset:
    """Scans of one split folder, listed by the first six characters of ``*_pc.npz`` names
    (3DETR's rule). ``dataset[i]`` returns load_sunrgbd_scene plus ``sampled`` (num_points rows
    drawn with a generator seeded by seed + i; with replacement only if the cloud is smaller)."""

    def __init__(self, folder, num_points=4096, seed=0):
        if not os.path.isdir(folder):
            raise RuntimeError(f"ds3d.htx.SunRgbdDataset: {folder} is not a directory")
        names = sorted(f for f in os.listdir(folder) if re.fullmatch(r"\d{6}_pc\.npz", f))
        self.folder, self.scans = folder, [f[:6] for f in names]
        self.num_points, self.seed = int(num_points), int(seed)

    def __len__(self):
        return len(self.scans)

    def __getitem__(self, i):
        scene = load_sunrgbd_scene(self.folder, self.scans[i])
        rng = np.random.default_rng(self.seed + i)
        n = len(scene["points"])
        if n == 0:
            raise RuntimeError(f"ds3d.htx.SunRgbdDataset: scan {self.scans[i]} has no points")
        idx = rng.choice(n, self.num_points, replace=n < self.num_points)
        scene["sampled"] = scene["points"][idx]
        scene["scan"] = self.scans[i]
        return scene
