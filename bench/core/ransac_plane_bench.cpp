// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d::ransac_plane with 1000 iterations and the early stop disabled (confidence = 1), t = 1 cm,
// on the ~300k and ~1M point room frames: the equal-work comparison with Open3D and PCL.
#include <benchmark/benchmark.h>

#include "ds3d/preprocess/ransac_plane.hpp"
#include "preprocess_clouds.hpp"

namespace {

void BM_RansacPlane1000(benchmark::State& state) {
  const ds3d::Points3f& p = ds3d::bench::room_cloud(state.range(0));
  ds3d::RansacPlaneParams params;
  params.distance_threshold = 0.01;
  params.max_iterations = 1000;
  params.confidence = 1.0;
  params.num_threads = static_cast<int>(state.range(1));
  std::size_t inliers = 0;
  for (auto _ : state) {
    const auto r = ds3d::ransac_plane(p, params);
    inliers = r.inliers.size();
    benchmark::DoNotOptimize(r.plane.data());
  }
  state.counters["points"] = static_cast<double>(p.rows());
  state.counters["inliers"] = static_cast<double>(inliers);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * p.rows() * 1000);
}
BENCHMARK(BM_RansacPlane1000)
    ->ArgsProduct({{300'000, 1'000'000}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
