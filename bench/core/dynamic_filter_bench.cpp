// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Cost of the box-gated HDBSCAN dynamic filter per frame: N keypoints spread over a 640×480
// frame (a wall at 3 m) with one person box covering a given fraction of the image (a slab at
// 1.5 m). Arguments: {keypoints, box area in percent of the image, metric gates}: with gates 1
// the box also carries a solid (an oriented 3-D box holding everything in its rectangle between
// 1.2 and 3.2 m, so the same keypoints are clustered) and the frame a support plane 2 m below the
// camera (no keypoint on it): the cost of the gates alone.
#include <benchmark/benchmark.h>

#include <cmath>
#include <optional>
#include <vector>

#include "ds3d/dynamic/dynamic_filter.hpp"
#include "support/synthetic.hpp"

namespace {

void BM_DynamicFilter(benchmark::State& state) {
  const auto n = static_cast<int>(state.range(0));
  const double frac = static_cast<double>(state.range(1)) / 100.0;
  const double side = std::sqrt(frac);  // box covers side × side of each image dimension
  const float u0 = static_cast<float>(320.0 - 320.0 * side);
  const float u1 = static_cast<float>(320.0 + 320.0 * side - 1.0);
  const float v0 = static_cast<float>(240.0 - 240.0 * side);
  const float v1 = static_cast<float>(240.0 + 240.0 * side - 1.0);
  ds3d::test::Rng rng(1);
  ds3d::Keypoints3f kp(n, 3);
  for (int i = 0; i < n; ++i) {
    const auto u = static_cast<float>(rng.uniform(0, 639));
    const auto v = static_cast<float>(rng.uniform(0, 479));
    const bool person =
        u >= u0 + 0.2F * (u1 - u0) && u <= u1 - 0.2F * (u1 - u0) && v >= v0 && v <= v1;
    kp.row(i) << u, v, person ? 1.5F + static_cast<float>(rng.uniform(-0.15, 0.15)) : 3.0F;
  }
  ds3d::ImageBox box;
  box.x_min = u0;
  box.x_max = u1;
  box.y_min = v0;
  box.y_max = v1;
  const ds3d::PinholeCamera cam;
  std::optional<Eigen::Vector4f> plane;
  if (state.range(2) != 0) {
    ds3d::SolidBox solid;
    solid.centre = Eigen::Vector3f(0.0F, 0.0F, 2.2F);
    solid.half = Eigen::Vector3f(static_cast<float>(320.0 * side / cam.fx * 3.2 + 0.1),
                                 static_cast<float>(240.0 * side / cam.fy * 3.2 + 0.1), 1.0F);
    solid.margin = 0.15F;
    box.solid = solid;
    plane = Eigen::Vector4f(0.0F, -1.0F, 0.0F, 2.0F);
  }
  const std::vector<ds3d::ImageBox> boxes{box};
  ds3d::DynamicFeatureFilter filter;
  int dyn = 0;
  for (auto _ : state) {
    const auto r = filter.filter(kp, boxes, cam, plane);
    dyn = r.num_dynamic;
    benchmark::DoNotOptimize(r.dynamic.data());
  }
  state.counters["dynamic"] = dyn;
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_DynamicFilter)
    ->ArgsProduct({{500, 1000, 2000}, {10, 40, 90}, {0, 1}})
    ->ArgNames({"n", "box", "gates"})
    ->Unit(benchmark::kMillisecond);

}  // namespace
