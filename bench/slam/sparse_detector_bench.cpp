// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HTx-lite inference time per frame (network + post-processing; the part head separately),
// fast and quality profiles, 4,096 gravity-aligned points, 1 or 2 threads. Weights are random
// (timing does not depend on their values). Compare with PyTorch: scripts/bench_htx_vs_torch.py.
#include <benchmark/benchmark.h>

#include <string>

#include "ds3d/sparse_detector.hpp"
#include "ds3d/weights_io.hpp"
#include "support/htx_random.hpp"

namespace {

const ds3d::SparseDetector& detector(int profile) {
  static const ds3d::SparseDetector fast = ds3d::SparseDetector::from_weights(
      ds3d::WeightsFile::parse(ds3d::test::random_htx_file(ds3d::DetectorConfig::make_profile("fast"), 1)));
  static const ds3d::SparseDetector quality = ds3d::SparseDetector::from_weights(
      ds3d::WeightsFile::parse(ds3d::test::random_htx_file(ds3d::DetectorConfig::make_profile("quality"), 1)));
  return profile == 0 ? fast : quality;
}

// Args: profile (0 fast, 1 quality), threads, part head (0/1).
void BM_HtxDetect(benchmark::State& state) {
  const auto& det = detector(static_cast<int>(state.range(0)));
  const auto pts = ds3d::test::htx_scene(4096, 7);
  const ds3d::DetectOptions opt{.num_threads = static_cast<int>(state.range(1)), .part_logits = state.range(2) != 0};
  for (auto _ : state) {
    auto out = det.run(pts, opt);
    benchmark::DoNotOptimize(out.proposals.data());
  }
  state.SetLabel(det.config().profile + (opt.part_logits ? "+parts" : ""));
  state.SetItemsProcessed(state.iterations() * pts.rows());
}
BENCHMARK(BM_HtxDetect)
    ->ArgNames({"profile", "threads", "parts"})
    ->ArgsProduct({{0, 1}, {1, 2}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);

}  // namespace
