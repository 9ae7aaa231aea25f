// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d::remove_radius_outliers (R = 0.05 m, k = 16) on the ~300k and ~1M point room frames.
#include <benchmark/benchmark.h>

#include "ds3d/preprocess/radius_outlier.hpp"
#include "preprocess_clouds.hpp"

namespace {

void BM_RadiusOutlier(benchmark::State& state) {
  const ds3d::Points3f& p = ds3d::bench::room_cloud(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  const auto search = state.range(2) == 0 ? ds3d::RadiusSearch::kGrid : ds3d::RadiusSearch::kKdTree;
  std::size_t kept = 0;
  for (auto _ : state) {
    const auto r = ds3d::remove_radius_outliers(
        p, {.radius = 0.05, .min_neighbors = 16, .num_threads = threads, .search = search});
    kept = r.kept.size();
    benchmark::DoNotOptimize(r.kept.data());
  }
  state.counters["points"] = static_cast<double>(p.rows());
  state.counters["kept"] = static_cast<double>(kept);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * p.rows());
}
BENCHMARK(BM_RadiusOutlier)
    ->ArgsProduct({{300'000, 1'000'000}, {1, 2}, {0, 1}})  // points, threads, grid / kd-tree
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
