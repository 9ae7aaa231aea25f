# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""HTx-lite detector: PyTorch reference (3DETR + Part-A2 part head), targets, losses, export.

torch is imported lazily, so ``import ds3d`` works without it. Public API:
``build_model(profile='fast'|'quality', seed=0)``, ``export(model, path)``,
``reference_detect(model, points)`` -> numpy (M, 9), ``part_targets``, ``scene_loss``,
``load_sunrgbd_scene``. See docs/htx.md.
"""
import importlib

_LAZY = {
    "build_model": "model", "HTx": "model", "make_config": "config", "PROFILES": "config",
    "export": "weights", "read_safetensors": "weights", "write_safetensors": "weights",
    "folded_tensors": "weights", "reference_detect": "detect", "postprocess": "detect",
    "part_targets": "targets", "box_targets": "targets", "scene_loss": "losses",
    "detection_loss": "losses", "part_loss": "losses", "hungarian_match": "losses",
    "nms_3d_same_class": "nms", "generalized_iou_3d": "boxes", "load_sunrgbd_scene": "sunrgbd",
    "SunRgbdDataset": "sunrgbd",
}

__all__ = sorted(_LAZY)


def __getattr__(name):
    if name in ("boxes", "ops", "losses", "targets", "nms", "sunrgbd", "config", "model", "weights", "detect"):
        return importlib.import_module(f".{name}", __name__)
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'ds3d.htx' has no attribute {name!r}")
