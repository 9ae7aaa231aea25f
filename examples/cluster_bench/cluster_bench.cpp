// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// What this shows: how to microbenchmark ds3d::hdbscan (header-only, ds3d::core) with Google
// Benchmark in your own project, on data shaped like yours. Two families:
//   BM_HdbscanBlobs/n/D      n points in D dimensions: 5 Gaussian blobs + 10 % uniform noise
//                            (min_cluster_size 15, min_samples 10: the sweep.py settings);
//   BM_HdbscanKeypoints/n    n keypoints (u, v, depth) of one person box, scaled as the dynamic
//                            filter scales them (pixels -> metres at the box's depth).
// Each reports CPU time, points/s (items_per_second) and the clusters found (a counter you can
// check by eye: 5 for the blobs, about 2 for the box: the person and the wall behind).
// Run: cluster_bench [--benchmark_filter=Keypoints] [--benchmark_min_time=0.1]
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include <ds3d/cluster/hdbscan.hpp>

namespace {

// n points in `dim` dimensions: 5 blobs (σ = 0.5) with centres in [-10, 10]^dim, 10 % noise.
ds3d::RowMatrixXd blobs(Eigen::Index n, Eigen::Index dim, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> box(-10.0, 10.0);
  std::normal_distribution<double> gauss(0.0, 0.5);
  ds3d::RowMatrixXd centres(5, dim);
  for (Eigen::Index i = 0; i < centres.size(); ++i) centres.data()[i] = box(rng);
  ds3d::RowMatrixXd x(n, dim);
  for (Eigen::Index i = 0; i < n; ++i) {
    const bool noise = i % 10 == 9;
    for (Eigen::Index j = 0; j < dim; ++j) {
      x(i, j) = noise ? box(rng) : centres(i % 5, j) + gauss(rng);
    }
  }
  return x;
}

// n keypoints in a 160 x 360 px person box: 60 % on a person at 2 m (σ 5 cm of body depth),
// 40 % on the wall at 4 m seen around them. Rows (u, v, z) in px, px, m.
ds3d::RowMatrixXd box_keypoints(Eigen::Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  ds3d::RowMatrixXd x(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) {
    const bool person = u01(rng) < 0.6;
    const double u = person ? 240.0 + 80.0 * u01(rng) : 200.0 + 160.0 * u01(rng);
    x(i, 0) = u;
    x(i, 1) = 80.0 + 360.0 * u01(rng);
    x(i, 2) = person ? 2.0 + 0.05 * gauss(rng) : 4.0 + 0.02 * gauss(rng);
  }
  return x;
}

void BM_HdbscanBlobs(benchmark::State& state) {
  const ds3d::RowMatrixXd x = blobs(state.range(0), state.range(1), 42);
  ds3d::HdbscanParams p;
  p.min_cluster_size = 15;
  p.min_samples = 10;
  int clusters = 0;
  for (auto _ : state) {
    const ds3d::HdbscanResult r = ds3d::hdbscan(x, p);
    clusters = r.num_clusters;
    benchmark::DoNotOptimize(r.labels.data());
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.counters["clusters"] = clusters;
}
BENCHMARK(BM_HdbscanBlobs)
    ->ArgsProduct({{1000, 4000, 16000}, {2, 3, 5}})
    ->ArgNames({"n", "D"})
    ->Unit(benchmark::kMillisecond);

void BM_HdbscanKeypoints(benchmark::State& state) {
  const ds3d::RowMatrixXd x = box_keypoints(state.range(0), 7);
  // The dynamic filter's scaling: pixels -> metres at the median depth (~2 m at fx = 525).
  const double px_to_m = 2.0 / 525.0;
  const std::vector<double> scale{px_to_m, px_to_m, 1.0};
  ds3d::HdbscanParams p;
  p.min_cluster_size = 8;  // DynamicFilterParams defaults
  p.min_samples = 4;
  int clusters = 0;
  for (auto _ : state) {
    const ds3d::HdbscanResult r = ds3d::hdbscan(x, p, scale);
    clusters = r.num_clusters;
    benchmark::DoNotOptimize(r.labels.data());
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.counters["clusters"] = clusters;
}
BENCHMARK(BM_HdbscanKeypoints)
    ->Arg(100)
    ->Arg(400)
    ->Arg(1600)
    ->ArgName("n")
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
