# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Writes HTx-lite training or test shards from the synthetic generator (ds3d.htx.data).

    python3 -m ds3d.htx.make_dataset --out /work/htx_data/train --split train --frames 3000 --seed 1
    python3 -m ds3d.htx.make_dataset --out /work/htx_data/test --split test --frames 400 --seed 1

Splits use disjoint scene seeds (so different furniture, people, clothes and body sizes; test
also holds walkers taller than any trained on). Keep the output outside git.
"""
import argparse
import json
import sys
import time

from . import data


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--split", default="train", choices=("train", "val", "test"))
    p.add_argument("--frames", type=int, required=True, help="samples to write, >= 1")
    p.add_argument("--seed", type=int, default=1, help="base seed, >= 0")
    p.add_argument("--frames-per-scene", type=int, default=8)
    p.add_argument("--shard-size", type=int, default=256)
    p.add_argument("--crowd-share", type=float, default=0.0,
                   help="share of scenes drawn from the crowd_* stress scenarios, in [0, 1]")
    a = p.parse_args(argv)
    if a.frames < 1 or a.seed < 0 or a.frames_per_scene < 1 or a.shard_size < 1:
        p.error("--frames, --frames-per-scene and --shard-size must be >= 1 and --seed >= 0")
    if not 0.0 <= a.crowd_share <= 1.0:
        p.error(f"--crowd-share must be in [0, 1] (got {a.crowd_share})")
    t0 = time.time()
    last = [0.0]

    def log(msg):
        if time.time() - last[0] > 10:
            sys.stderr.write(f"[{time.time() - t0:6.0f} s] {msg}\n")
            last[0] = time.time()

    summary = data.generate(a.out, a.split, a.frames, a.seed, a.frames_per_scene, a.shard_size, log,
                            crowd_share=a.crowd_share)
    summary["seconds"] = round(time.time() - t0, 1)
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
