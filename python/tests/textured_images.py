# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Shared test input: a seeded, richly textured RGB image that ORB finds features all over."""
import numpy as np


def textured(seed, h=480, w=640):
    """(h, w, 3) uint8: 1,500 random coloured squares (3-19 px) on grey, deterministic by seed."""
    rng = np.random.default_rng(seed)
    img = np.full((h, w, 3), 90, np.uint8)
    for _ in range(1500):
        y, x = rng.integers(0, h - 20), rng.integers(0, w - 20)
        s = rng.integers(3, 20)
        img[y:y + s, x:x + s] = rng.integers(0, 255, 3)
    return img
