#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Writes the C++ parity fixtures tests/data/htx/: a small random-initialised HTx model
(tiny_weights.safetensors, ~70 kB) and a fixed input with the PyTorch outputs
(tiny_expected.safetensors). Full-size profiles are checked at test time by
python/tests/htx_parity_test.py instead (their weights are 3.8 MB each).

Usage: PYTHONPATH=build/python /usr/bin/python3 scripts/make_htx_fixtures.py [out_dir]
"""
import os
import sys

import numpy as np

from ds3d import htx

TINY = dict(num_centres=96, sa_mlp=[16, 32, 32], d_model=32, num_heads=4, enc_ffn=32, dec_ffn=32,
            num_queries=16, head_hidden=32, part_hidden=16, num_classes=2, class_names=["person", "chair"])


def main(out_dir):
    os.makedirs(out_dir, exist_ok=True)
    model = htx.build_model("fast", seed=11, **TINY)
    htx.export(model, os.path.join(out_dir, "tiny_weights.safetensors"))
    rng = np.random.default_rng(5)
    pts = np.concatenate([rng.uniform([-1.5, 1.0, 0.0], [1.5, 3.0, 2.0], (700, 3)),
                          rng.uniform([0.0, 2.0, 0.0], [0.4, 2.4, 1.7], (300, 3))]).astype(np.float32)
    pts = pts[rng.permutation(len(pts))]
    rows, d = htx.reference_detect(model, pts, return_details=True)
    props = np.concatenate([d["center"], d["size"], d["angle"][:, None]], axis=1)
    f32 = lambda a: np.asarray(a, dtype=np.float32)
    htx.write_safetensors(os.path.join(out_dir, "tiny_expected.safetensors"), {
        "points": pts, "boxes": f32(rows), "proposals": f32(props), "objectness": f32(d["objectness"]),
        "class_prob": f32(d["sem_cls_prob"]), "part_logits": f32(d["part_logits"]),
        "centre_indices": f32(d["centre_indices"]), "query_indices": f32(d["query_indices"]),
    }, {"generator": "scripts/make_htx_fixtures.py"})
    print(f"wrote {out_dir}: {len(rows)} boxes, {len(pts)} points")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "tests", "data", "htx"))
