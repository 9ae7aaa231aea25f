// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HDBSCAN timings (single thread, min_cluster_size 15, min_samples 10): per-frame keypoints
// (u, v, 100 × depth) and 3-D Gaussian blobs with 20% uniform noise. The 1M-point case is a
// separate benchmark (BM_HdbscanBlobs1M) so `--benchmark_filter=-1M` skips it; see
// docs/benchmarks.md for the commands and the reference timings.
#include <benchmark/benchmark.h>

#include "ds3d/cluster/hdbscan.hpp"
#include "support/keypoints.hpp"
#include "support/synthetic.hpp"

namespace {

ds3d::HdbscanParams bench_params(ds3d::MstAlgorithm algorithm) {
  ds3d::HdbscanParams p;
  p.min_cluster_size = 15;
  p.min_samples = 10;
  p.algorithm = algorithm;
  return p;
}

void run(benchmark::State& state, const ds3d::RowMatrixXd& x, ds3d::MstAlgorithm algorithm) {
  const auto p = bench_params(algorithm);
  int clusters = 0;
  for (auto _ : state) {
    const auto r = ds3d::hdbscan(x, p);
    clusters = r.num_clusters;
    benchmark::DoNotOptimize(r.labels.data());
  }
  state.counters["clusters"] = clusters;
  state.SetItemsProcessed(state.iterations() * x.rows());
}

void BM_HdbscanKeypoints(benchmark::State& state) {
  const auto x = ds3d::test::person_keypoints(static_cast<std::size_t>(state.range(0)), 42);
  run(state, x, static_cast<ds3d::MstAlgorithm>(state.range(1)));
}
BENCHMARK(BM_HdbscanKeypoints)
    ->ArgsProduct({{500, 2000}, {0, 1, 2}})
    ->ArgNames({"n", "algo"})
    ->Unit(benchmark::kMillisecond);

void BM_HdbscanBlobs(benchmark::State& state) {
  const auto x =
      ds3d::test::gaussian_blobs(static_cast<std::size_t>(state.range(0)), 3, 10, 0.2, 7, 10.0, 1.0)
          .x;
  run(state, x, static_cast<ds3d::MstAlgorithm>(state.range(1)));
}
BENCHMARK(BM_HdbscanBlobs)
    ->Args({1'000, 0})
    ->Args({1'000, 1})
    ->Args({1'000, 2})
    ->Args({10'000, 0})
    ->Args({10'000, 1})
    ->Args({10'000, 2})
    ->Args({100'000, 0})
    ->ArgNames({"n", "algo"})
    ->Unit(benchmark::kMillisecond);

void BM_HdbscanBlobs1M(benchmark::State& state) {
  const auto x = ds3d::test::gaussian_blobs(1'000'000, 3, 10, 0.2, 7, 10.0, 1.0).x;
  run(state, x, ds3d::MstAlgorithm::kAuto);
}
BENCHMARK(BM_HdbscanBlobs1M)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace
