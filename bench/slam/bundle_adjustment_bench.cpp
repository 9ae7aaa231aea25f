// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Local bundle adjustment (include/ds3d/bundle_adjustment.hpp) of a synthetic window: K keyframes
// on a sideways track looking at P points 2-5 m away, every point seen (with depth) by every
// keyframe, 0.5 px pixel noise, 1 % gross outliers, the first keyframe fixed and the others
// started 3 cm / 0.6° off. Args: keyframes, points. Ceres runs single-threaded.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <vector>

#include "ds3d/slam/bundle_adjustment.hpp"
#include "support/synthetic.hpp"

namespace {

using ds3d::slam::BaObservation;

struct Window {
  std::vector<Eigen::Isometry3d> init;
  std::vector<std::uint8_t> fixed;
  std::vector<Eigen::Vector3d> points;
  std::vector<BaObservation> obs;
};

constexpr ds3d::slam::StereoIntrinsics kK{525.0, 525.0, 319.5, 239.5, 40.0};

Window make_window(int keyframes, int points) {
  ds3d::test::Rng rng(7);
  Window w;
  std::vector<Eigen::Isometry3d> truth;
  for (int i = 0; i < keyframes; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // T_cam_world
    T.linear() = Eigen::AngleAxisd(0.02 * i, Eigen::Vector3d::UnitY()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(-0.1 * i, 0.0, 0.0);
    truth.push_back(T);
  }
  std::vector<Eigen::Vector3d> pts_true;
  for (int j = 0; j < points; ++j) {
    pts_true.emplace_back(rng.uniform(-1.5, 1.5), rng.uniform(-1.0, 1.0), rng.uniform(2.0, 5.0));
  }
  for (int i = 0; i < keyframes; ++i) {
    for (int j = 0; j < points; ++j) {
      const Eigen::Vector3d pc =
          truth[static_cast<std::size_t>(i)] * pts_true[static_cast<std::size_t>(j)];
      BaObservation o;
      o.keyframe = i;
      o.point = j;
      o.obs.pixel = {kK.fx * pc.x() / pc.z() + kK.cx + 0.5 * rng.normal(),
                     kK.fy * pc.y() / pc.z() + kK.cy + 0.5 * rng.normal()};
      if (rng.uniform() < 0.01) o.obs.pixel.x() += 60.0;  // gross outlier
      o.obs.has_depth = true;
      o.obs.u_right = o.obs.pixel.x() - kK.bf / pc.z();
      w.obs.push_back(o);
    }
  }
  w.init = truth;
  w.fixed.assign(static_cast<std::size_t>(keyframes), 0);
  w.fixed[0] = 1;
  ds3d::slam::Vector6d delta;
  delta << 0.01, -0.01, 0.005, 0.03, 0.02, -0.02;
  for (std::size_t i = 1; i < w.init.size(); ++i)
    w.init[i] = ds3d::slam::pose_plus(truth[i], delta);
  w.points = pts_true;
  for (auto& p : w.points) p += Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()) * 0.02;
  return w;
}

void BM_LocalBundleAdjustment(benchmark::State& state) {
  const Window w = make_window(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  double final_cost = 0.0;
  std::size_t outliers = 0;
  for (auto _ : state) {
    const auto r = ds3d::slam::local_bundle_adjustment(kK, w.init, w.fixed, w.points, w.obs);
    final_cost = r.final_cost;
    outliers = 0;
    for (const auto o : r.outlier) outliers += o;
    benchmark::DoNotOptimize(r.poses.data());
  }
  state.counters["observations"] = static_cast<double>(w.obs.size());
  state.counters["outliers"] = static_cast<double>(outliers);
  state.counters["final_cost"] = final_cost;
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(w.obs.size()));
}
// ORB-SLAM2's local window is the covisible keyframes of the new one: 5-20 in practice.
BENCHMARK(BM_LocalBundleAdjustment)
    ->Args({5, 200})
    ->Args({10, 500})
    ->Args({20, 1000})
    ->Unit(benchmark::kMillisecond);

}  // namespace
