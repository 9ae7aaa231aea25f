// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Demo step 40: generate a short synthetic walking_xyz sequence, then evaluate a trajectory
// against its ground truth with ATE/RPE and write the plot. Until the SLAM front-end lands, the
// "estimate" is the ground truth with drift and noise added.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <random>

#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/slam/synth.hpp"
#include "ds3d/slam/trajectory_plot.hpp"
#include "ds3d_demo/demo.hpp"

namespace {

void run_eval_demo(const ds3d::demo::Context& ctx) {
  const auto dir = ctx.out_dir / "synth_walking_xyz";
  ds3d::synth::SynthOptions opt;
  opt.scenario = ds3d::synth::Scenario::kWalkingXyz;
  opt.num_frames = ctx.quick ? 15 : 90;
  opt.seed = ctx.seed;
  const auto s = ds3d::synth::generate_sequence(dir, opt, /*overwrite=*/true);
  const auto ds = ds3d::RgbdDataset::open(dir);
  std::printf("  generated %zu frames into %s (render %.1f ms/frame CPU, %.0f dynamic px/frame)\n",
              s.frames, dir.string().c_str(),
              1e3 * s.render_seconds / static_cast<double>(s.frames),
              static_cast<double>(s.dynamic_pixels) / static_cast<double>(s.frames));
  std::printf("  read back: %zu associated rgb-d pairs, camera fx %.1f\n", ds.size(),
              ds.camera().fx);

  // "Estimate": ground truth at the frame stamps, with a random walk drift and 3 mm noise,
  // expressed in a rotated, shifted frame (as a SLAM system's own world frame would be).
  const auto gt = ds3d::read_tum_trajectory(*ds.groundtruth_path());
  std::mt19937_64 rng(ctx.seed);
  std::normal_distribution<double> noise(0.0, 0.003);
  std::normal_distribution<double> drift_step(0.0, 0.0015);
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.linear() = Eigen::AngleAxisd(0.8, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  frame.translation() = Eigen::Vector3d(1.0, -2.0, 0.3);
  ds3d::Trajectory est;
  Eigen::Vector3d drift = Eigen::Vector3d::Zero();
  for (const auto& e : ds.entries()) {
    const auto it = std::min_element(gt.begin(), gt.end(), [&](const auto& a, const auto& b) {
      return std::abs(a.timestamp - e.timestamp) < std::abs(b.timestamp - e.timestamp);
    });
    drift += Eigen::Vector3d(drift_step(rng), drift_step(rng), drift_step(rng));
    ds3d::TimedPose p{e.timestamp, it->T_world_cam};
    p.T_world_cam.translation() += drift + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    p.T_world_cam = frame * p.T_world_cam;
    est.push_back(p);
  }
  ds3d::write_tum_trajectory(dir / "estimate_noisy.txt", est);
  const auto ate = ds3d::evaluate_ate(gt, est);
  const auto rpe =
      ds3d::evaluate_rpe(gt, est, {.delta = 1, .delta_unit = ds3d::DeltaUnit::kFrames});
  std::printf("  ATE (SE(3)-aligned): %zu pairs, rmse %.4f m, median %.4f m, max %.4f m\n",
              ate.compared_pose_pairs, ate.rmse, ate.median, ate.max);
  std::printf("  RPE (1 frame): %zu pairs, trans rmse %.4f m, rot rmse %.3f deg\n",
              rpe.compared_pose_pairs, rpe.translational.rmse, rpe.rotational.rmse);
  const auto plot = ctx.out_dir / "eval_ate.png";
  ds3d::write_ate_plot(plot, gt, ate,
                       {.title = "demo: noisy ground truth vs synthetic walking_xyz"});
  std::printf("  plot: %s  (same numbers: build/bin/ds3d-eval ate %s %s)\n", plot.string().c_str(),
              (dir / "groundtruth.txt").string().c_str(),
              (dir / "estimate_noisy.txt").string().c_str());
}

}  // namespace

DS3D_DEMO_STEP(40, "evaluation: synthetic walking_xyz sequence, ATE/RPE, plot", run_eval_demo);
