// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d::voxel_grid on a rendered room frame (~300k points) and a 1280x800 frame (~1M points),
// in sensor (row-major) order and shuffled.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

#include "ds3d/preprocess/voxel_grid.hpp"
#include "preprocess_clouds.hpp"

namespace {

void BM_VoxelGrid(benchmark::State& state) {
  const ds3d::Points3f& p = ds3d::bench::room_cloud(state.range(0));
  const double leaf = static_cast<double>(state.range(1)) / 1000.0;
  const int threads = static_cast<int>(state.range(2));
  std::size_t voxels = 0;
  for (auto _ : state) {
    const auto r = ds3d::voxel_grid(p, {.leaf_size = leaf, .num_threads = threads});
    voxels = r.counts.size();
    benchmark::DoNotOptimize(r.centroids.data());
  }
  state.counters["points"] = static_cast<double>(p.rows());
  state.counters["voxels"] = static_cast<double>(voxels);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * p.rows());
}
// Args: points (300k or 1M frame), leaf [mm], threads.
BENCHMARK(BM_VoxelGrid)
    ->ArgsProduct({{300'000, 1'000'000}, {10, 50}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Small clouds (the first N points of the 300k frame, in pixel order, as a depth frame at a
// coarser stride gives them) with one reused workspace: range(2) threads; range(3) = 1 forces the
// parallel passes (parallel_min_points = 0), 0 keeps the default threshold (one thread below it).
void BM_VoxelGridSmall(benchmark::State& state) {
  const ds3d::Points3f& all = ds3d::bench::room_cloud(300'000);
  const ds3d::Points3f p = all.topRows(std::min<Eigen::Index>(state.range(0), all.rows()));
  ds3d::VoxelGridParams vp;
  vp.leaf_size = 0.05;
  vp.num_threads = static_cast<int>(state.range(1));
  if (state.range(2) != 0) vp.parallel_min_points = 0;
  ds3d::VoxelGridWorkspace ws;
  for (auto _ : state) {
    const auto r = ds3d::voxel_grid(p, vp, ws);
    benchmark::DoNotOptimize(r.centroids.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * p.rows());
}
// Args: points, threads, forced parallel (1) or the default threshold (0).
BENCHMARK(BM_VoxelGridSmall)
    ->ArgsProduct({{10'000, 100'000}, {1, 2}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The per-frame use: one VoxelGridWorkspace kept across calls (no scratch allocation).
// Times voxel_grid on `p` with one reused workspace; leaf [mm] = state.range(1).
void run_with_workspace(benchmark::State& state, const ds3d::Points3f& p) {
  const double leaf = static_cast<double>(state.range(1)) / 1000.0;
  ds3d::VoxelGridWorkspace ws;
  std::size_t voxels = 0;
  for (auto _ : state) {
    const auto r = ds3d::voxel_grid(p, {.leaf_size = leaf}, ws);
    voxels = r.counts.size();
    benchmark::DoNotOptimize(r.centroids.data());
  }
  state.counters["voxels"] = static_cast<double>(voxels);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * p.rows());
}

void BM_VoxelGridWorkspace(benchmark::State& state) {
  run_with_workspace(state, ds3d::bench::room_cloud(state.range(0)));
}
// Args: points, leaf [mm]; one thread.
BENCHMARK(BM_VoxelGridWorkspace)
    ->ArgsProduct({{300'000, 1'000'000}, {10, 50}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The same frame with its points in a fixed random order (no sensor-order locality: the sparse
// path's radix sort then takes its three-pass fallback; see docs/preprocess.md).
const ds3d::Points3f& shuffled_room_cloud(std::int64_t points) {
  static ds3d::Points3f small;
  static ds3d::Points3f large;
  ds3d::Points3f& q = points > 400'000 ? large : small;
  if (q.rows() == 0) {
    const ds3d::Points3f& p = ds3d::bench::room_cloud(points);
    std::vector<Eigen::Index> order(static_cast<std::size_t>(p.rows()));
    std::iota(order.begin(), order.end(), Eigen::Index{0});
    std::shuffle(order.begin(), order.end(), std::mt19937_64(7));
    q.resize(p.rows(), 3);
    for (Eigen::Index i = 0; i < p.rows(); ++i)
      q.row(i) = p.row(order[static_cast<std::size_t>(i)]);
  }
  return q;
}

void BM_VoxelGridShuffled(benchmark::State& state) {
  run_with_workspace(state, shuffled_room_cloud(state.range(0)));
}
// Args: points, leaf [mm]; one thread, reused workspace.
BENCHMARK(BM_VoxelGridShuffled)
    ->ArgsProduct({{300'000, 1'000'000}, {10}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
