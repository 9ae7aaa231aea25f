# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""HTx-lite architecture profiles (docs/htx_spec.md §6.2; "fast" and "quality").

Every number the C++ ``ds3d::SparseDetector`` needs is in this dict; the exporter writes it as the
JSON string ``config`` in the weights file's ``__metadata__``.
"""
import copy

_COMMON = {
    "format_version": 1,
    "sa_radius": 0.25,          # ball-query radius [m]
    "sa_samples": 32,           # samples per ball, "first by index" (spec §3.2)
    "sa_mlp": [32, 64, 128],    # shared MLP widths (3 -> 32 -> 64 -> 128)
    "d_model": 128,
    "num_heads": 4,
    "enc_layers": 2,
    "enc_ffn": 128,
    "dec_layers": 3,
    "dec_ffn": 128,
    "num_queries": 64,
    "num_classes": 1,           # K; the class head has K + 1 outputs (last = background)
    "class_names": ["person"],
    "num_angle_bins": 12,
    "head_hidden": 128,
    "part_hidden": 64,
    "layer_norm_eps": 1e-5,
    "min_points_in_box": 5,
    "nms_iou": 0.25,
    "score_threshold": 0.05,    # on objectness (spec §3.8); tune on validation data
    "min_size_extent": 0.1,     # size = sigmoid * max(scene extent, this) [m]
    "fps_padding_norm2": 1e-3,  # points with |p|^2 <= this are never picked by FPS (spec §3.2)
    "bn_folded": True,
    "in_proj": "packed_qkv",    # attention in_proj_weight rows: q, then k, then v
}

PROFILES = {
    "fast": dict(_COMMON, profile="fast", num_centres=384),
    "quality": dict(_COMMON, profile="quality", num_centres=512),
}


def make_config(profile="fast", **overrides):
    """Returns a fresh config dict for ``profile`` ('fast' or 'quality') with ``overrides`` applied.

    Raises ValueError on an unknown profile or override key, or an inconsistent class list.
    """
    if profile not in PROFILES:
        raise ValueError(f"ds3d.htx.make_config: profile must be 'fast' or 'quality' (got {profile!r})")
    cfg = copy.deepcopy(PROFILES[profile])
    for k, v in overrides.items():
        if k not in cfg:
            raise ValueError(f"ds3d.htx.make_config: unknown key {k!r}")
        cfg[k] = v
    if "num_classes" in overrides and "class_names" not in overrides:
        cfg["class_names"] = [f"class{i}" for i in range(cfg["num_classes"])]
    if len(cfg["class_names"]) != cfg["num_classes"]:
        raise ValueError("ds3d.htx.make_config: class_names must have num_classes entries "
                         f"(got {len(cfg['class_names'])} for {cfg['num_classes']})")
    if cfg["d_model"] % cfg["num_heads"] != 0 or cfg["d_model"] % 2 != 0:
        raise ValueError(f"ds3d.htx.make_config: d_model {cfg['d_model']} must be even and divisible "
                         f"by num_heads {cfg['num_heads']}")
    return cfg
