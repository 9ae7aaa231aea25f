#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Side-by-side timing of HTx-lite inference: PyTorch reference vs C++ ds3d.SparseDetector,
same weights, same 4,096-point input, one thread each (torch.set_num_threads(1), num_threads=1).
Runs are interleaved (torch, C++, torch, ...) so that load from other processes hits both alike;
the table gives the median and minimum per frame and the ratio of medians. --clock cpu (default)
times the calling thread's CPU time (time.thread_time): both sides run on that one thread, and
CPU time does not grow when other processes compete for the cores; --clock wall uses
time.perf_counter.

Usage: PYTHONPATH=build/python /usr/bin/python3 scripts/bench_htx_vs_torch.py [--reps 15] [--clock cpu|wall]
"""
import argparse
import os
import statistics
import sys
import tempfile
import time

import numpy as np
import torch

import ds3d
from ds3d import htx
from ds3d.htx import ops


class CachedSampling:
    """Context manager replacing ops.farthest_point_sample / ops.ball_query by cached results,
    to time PyTorch's network alone (its sampling runs as Python loops and sorts)."""

    def __init__(self):
        self.cache = {}
        self.saved = (ops.farthest_point_sample, ops.ball_query)

    def __enter__(self):
        fps, bq = self.saved

        def cached_fps(xyz, k, pad=1e-3):
            key = ("fps", xyz.shape[0], k)
            if key not in self.cache:
                self.cache[key] = fps(xyz, k, pad)
            return self.cache[key]

        def cached_bq(xyz, centres, r, s):
            key = ("bq", centres.shape[0])
            if key not in self.cache:
                self.cache[key] = bq(xyz, centres, r, s)
            return self.cache[key]

        ops.farthest_point_sample, ops.ball_query = cached_fps, cached_bq
        return self

    def __exit__(self, *exc):
        ops.farthest_point_sample, ops.ball_query = self.saved


def scene(n=4096, seed=7):
    rng = np.random.default_rng(seed)
    lo = np.array([[-2.0, 3.9, 0.0], [-2.0, 0.5, 0.0], [0.2, 1.5, 0.0], [-1.0, 2.5, 0.0]])
    hi = np.array([[2.0, 4.0, 2.5], [-1.9, 4.0, 2.5], [0.7, 2.0, 1.7], [0.0, 3.2, 0.8]])
    part = np.arange(n) % 4
    return rng.uniform(lo[part], hi[part]).astype(np.float32)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--profiles", default="fast,quality")
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu")
    args = ap.parse_args()
    clock = time.thread_time if args.clock == "cpu" else time.perf_counter
    torch.set_num_threads(1)
    pts = scene()
    xyz = torch.from_numpy(pts)
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}; ds3d {ds3d.__version__}; "
          f"{len(pts)} points; {args.reps} interleaved reps; {args.clock} time; "
          f"load {os.getloadavg()[0]:.1f}; ds3d SIMD {ds3d.build_info().simd}")
    print("| profile | part head | PyTorch [ms] | PyTorch, sampling cached [ms] | C++ [ms] | C++ min | "
          "speed-up | speed-up vs cached |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for profile in args.profiles.split(","):
            model = htx.build_model(profile, seed=0)
            path = os.path.join(tmp, f"{profile}.safetensors")
            htx.export(model, path)
            det = ds3d.SparseDetector.load(path)
            for parts in (False, True):
                tt, tn, tc = [], [], []
                cached = CachedSampling()
                with torch.no_grad():
                    model(xyz, with_parts=parts, all_layers=False)  # warm-up
                    det.run(pts, 1, parts)
                    for _ in range(args.reps):
                        t0 = clock()
                        model(xyz, with_parts=parts, all_layers=False)
                        t1 = clock()
                        with cached:
                            model(xyz, with_parts=parts, all_layers=False)
                        t2 = clock()
                        det.run(pts, 1, parts)
                        t3 = clock()
                        tt.append((t1 - t0) * 1e3)
                        tn.append((t2 - t1) * 1e3)
                        tc.append((t3 - t2) * 1e3)
                mt, mn, mc = statistics.median(tt), statistics.median(tn[1:]), statistics.median(tc)
                print(f"| {profile} | {'yes' if parts else 'no'} | {mt:.1f} | {mn:.1f} | {mc:.1f} | "
                      f"{min(tc):.1f} | {mt / mc:.1f}x | {mn / mc:.1f}x |")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
