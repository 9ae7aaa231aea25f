// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ATE and RPE cost over trajectory length (30 Hz estimate against 100 Hz ground truth).
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "ds3d/eval/trajectory_metrics.hpp"

namespace {

ds3d::Trajectory make(std::size_t n, double hz, double noise, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, noise);
  ds3d::Trajectory t;
  for (std::size_t i = 0; i < n; ++i) {
    const double s = static_cast<double>(i) / hz;
    ds3d::TimedPose p;
    p.timestamp = 1e9 + s;
    p.T_world_cam.linear() =
        Eigen::AngleAxisd(0.3 * std::sin(s), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    p.T_world_cam.translation() =
        Eigen::Vector3d(std::sin(s) + g(rng), std::cos(0.7 * s) + g(rng), 0.1 * s);
    t.push_back(p);
  }
  return t;
}

void BM_Ate(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto gt = make(n * 10 / 3, 100.0, 0.0, 1);
  const auto est = make(n, 30.0, 0.01, 2);
  for (auto _ : state) benchmark::DoNotOptimize(ds3d::evaluate_ate(gt, est).rmse);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * state.range(0)));
}
BENCHMARK(BM_Ate)->Arg(1'000)->Arg(30'000)->Unit(benchmark::kMillisecond);

void BM_RpeFixedDelta(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto gt = make(n * 10 / 3, 100.0, 0.0, 1);
  const auto est = make(n, 30.0, 0.01, 2);
  for (auto _ : state) {
    benchmark::DoNotOptimize(ds3d::evaluate_rpe(gt, est, {.max_pairs = 0}).translational.rmse);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * state.range(0)));
}
BENCHMARK(BM_RpeFixedDelta)->Arg(1'000)->Arg(30'000)->Unit(benchmark::kMillisecond);

}  // namespace
