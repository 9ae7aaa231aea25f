// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The per-frame ds3d::preprocess (640x480 depth -> detector input) and its back-projection stage.
#include <benchmark/benchmark.h>

#include "ds3d/preprocess/preprocess.hpp"
#include "preprocess_clouds.hpp"

namespace {

const ds3d::test::DepthFrame& frame() {
  static const ds3d::test::DepthFrame f = ds3d::test::render_room(1);
  return f;
}

void BM_DepthToPoints(benchmark::State& state) {
  const auto& f = frame();
  std::size_t n = 0;
  for (auto _ : state) {
    const auto r = ds3d::depth_to_points(f.depth.data(), 640, 480, 640, f.camera);
    n = static_cast<std::size_t>(r.points.rows());
    benchmark::DoNotOptimize(r.points.data());
  }
  state.counters["points"] = static_cast<double>(n);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * 640 * 480);
}
BENCHMARK(BM_DepthToPoints)->Unit(benchmark::kMillisecond)->UseRealTime();

// A distorted camera (Bonn's k1, k2): Arg 0 builds the ray table in every call (no
// DepthToPointsParams::rays), Arg 1 takes it from a PixelRayCache, as HtxSource does.
void BM_DepthToPointsDistorted(benchmark::State& state) {
  const auto& f = frame();
  ds3d::PinholeCamera cam = f.camera;
  cam.k1 = 0.04;
  cam.k2 = -0.1;
  ds3d::PixelRayCache cache;
  ds3d::DepthToPointsParams p;
  for (auto _ : state) {
    if (state.range(0) != 0) p.rays = cache.get(cam);
    const auto r = ds3d::depth_to_points(f.depth.data(), 640, 480, 640, cam, p);
    benchmark::DoNotOptimize(r.points.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * 640 * 480);
}
BENCHMARK(BM_DepthToPointsDistorted)
    ->ArgName("cached")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_Preprocess(benchmark::State& state) {
  const auto& f = frame();
  ds3d::PreprocessParams p;
  p.num_threads = static_cast<int>(state.range(0));
  ds3d::PreprocessResult r;
  for (auto _ : state) {
    r = ds3d::preprocess(f.depth.data(), 640, 480, 640, f.camera, p);
    benchmark::DoNotOptimize(r.points.data());
  }
  state.counters["out_points"] = static_cast<double>(r.points.rows());
  state.counters["voxels"] = static_cast<double>(r.num_voxels);
  state.counters["ground"] = static_cast<double>(r.num_ground);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * 640 * 480);
}
BENCHMARK(BM_Preprocess)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
