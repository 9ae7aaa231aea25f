#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Seed corpora of the libFuzzer targets that take binary input, from tests/data (make fuzz):
#   hdbscan_fuzz (4 parameter bytes + raw doubles), ate_plot_fuzz (gt NUL estimate) and
#   weights_stream_fuzz (the tiny weights fixture as exported, and again with its checksum).
import glob
import hashlib
import json
import os
import struct
import sys


def hdbscan_seeds(out):
    for k, path in enumerate(sorted(glob.glob("tests/data/hdbscan/*/points.csv"))[:12]):
        rows = [[float(v) for v in line.split(",")] for line in open(path) if line.strip()][:96]
        dims = len(rows[0])
        head = bytes([5 + k % 10, k % 7, k % 64, dims - 1])
        with open(os.path.join(out, f"seed{k}"), "wb") as f:
            f.write(head + b"".join(struct.pack("<d", v) for r in rows for v in r))


def ate_plot_seeds(out):
    for d in sorted(glob.glob("tests/data/trajectory/*/")):
        gt, est = os.path.join(d, "groundtruth.txt"), os.path.join(d, "estimate.txt")
        if os.path.exists(gt) and os.path.exists(est):
            with open(os.path.join(out, os.path.basename(d.rstrip("/"))), "wb") as f:
                f.write(open(gt, "rb").read()[:3000] + b"\0" + open(est, "rb").read()[:3000])


def weights_seeds(out):
    raw = open("tests/data/htx/tiny_weights.safetensors", "rb").read()
    open(os.path.join(out, "tiny_weights"), "wb").write(raw)
    (n,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8:8 + n])
    data = raw[8 + n:]
    header["__metadata__"]["tensors_sha256"] = hashlib.sha256(data).hexdigest()
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * ((8 - (8 + len(text)) % 8) % 8)
    open(os.path.join(out, "tiny_weights_checksum"), "wb").write(struct.pack("<Q", len(text)) + text + data)


def main(root):
    for name, fn in (("corpus_hdbscan", hdbscan_seeds), ("corpus_ate_plot", ate_plot_seeds),
                     ("corpus_weights_stream", weights_seeds)):
        d = os.path.join(root, name)
        os.makedirs(d, exist_ok=True)
        fn(d)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "build-fuzz")
