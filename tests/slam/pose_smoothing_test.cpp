// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/pose_smoothing.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "ds3d/errors.hpp"
#include "support/synthetic.hpp"

namespace {

using ds3d::slam::Observation;
using ds3d::slam::PoseSmoothingParams;
using ds3d::slam::SmoothingFrame;
using ds3d::slam::StereoIntrinsics;

const StereoIntrinsics kK{525.0, 525.0, 319.5, 239.5, 40.0};
constexpr double kDt = 1.0 / 30.0;

// World → camera pose of a camera at `c` looking along +z (world axes = camera axes).
Eigen::Isometry3d at(const Eigen::Vector3d& c) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = -c;
  return T;
}

Eigen::Vector3d centre(const Eigen::Isometry3d& T_cw) {
  return -(T_cw.linear().transpose() * T_cw.translation());
}

// A camera sliding sideways at 0.3 m/s past a far wall (3.5–4 m): `n` frames, each seeing
// `per_frame` wall points with depth, with `noise_px` pixel noise. The initial poses are each
// frame's own truth shifted sideways by up to `shift` [m] and turned by shift / 3.75 m, the pair
// that a far wall hardly tells apart. Returns the frames; `truth` gets the true poses.
std::vector<SmoothingFrame> far_wall(int n, int per_frame, double shift,
                                     std::vector<Eigen::Isometry3d>& truth, double noise_px = 1.0) {
  ds3d::test::Rng rng(11);
  std::vector<SmoothingFrame> frames;
  for (int i = 0; i < n; ++i) {
    const Eigen::Isometry3d T = at({0.3 * kDt * i, 0.0, 0.0});
    truth.push_back(T);
    SmoothingFrame f;
    f.timestamp = 100.0 + kDt * i;
    const double s = rng.uniform(-shift, shift);
    Eigen::Isometry3d off = Eigen::Isometry3d::Identity();
    off.linear() = Eigen::AngleAxisd(-s / 3.75, Eigen::Vector3d::UnitY()).toRotationMatrix();
    off.translation() = Eigen::Vector3d(-s, 0.0, 0.0);
    f.T_cam_world = off * T;
    for (int j = 0; j < per_frame; ++j) {
      const Eigen::Vector3d pc(rng.uniform(-1.5, 1.5), rng.uniform(-1.0, -0.3),
                               rng.uniform(3.5, 4.0));
      const Eigen::Vector3d pw = T.inverse() * pc;
      Observation o;
      o.pixel = {kK.fx * pc.x() / pc.z() + kK.cx + noise_px * rng.normal(),
                 kK.fy * pc.y() / pc.z() + kK.cy + noise_px * rng.normal()};
      o.u_right = o.pixel.x() - kK.bf / pc.z();
      o.has_depth = true;
      f.points.push_back(pw);
      f.observations.push_back(o);
    }
    frames.push_back(f);
  }
  return frames;
}

double rms_centre_error(const std::vector<Eigen::Isometry3d>& poses,
                        const std::vector<Eigen::Isometry3d>& truth, std::size_t from,
                        std::size_t to) {
  double sum = 0;
  for (std::size_t i = from; i < to; ++i)
    sum += (centre(poses[i]) - centre(truth[i])).squaredNorm();
  return std::sqrt(sum / static_cast<double>(to - from));
}

TEST(PoseSmoothing, TakesTheConstantVelocityPathWhereAFarWallLeavesTheShiftOpen) {
  std::vector<Eigen::Isometry3d> truth;
  const auto frames = far_wall(60, 25, 0.04, truth);
  // Each frame on its own (the pose-only optimum, as finish()'s refinement leaves it).
  std::vector<Eigen::Isometry3d> alone;
  for (const auto& f : frames) {
    alone.push_back(
        ds3d::slam::optimize_pose(kK, f.T_cam_world, f.points, f.observations).T_cam_world);
  }
  const auto smoothed = ds3d::slam::smooth_poses(kK, frames);
  ASSERT_EQ(smoothed.size(), frames.size());
  const double before = rms_centre_error(alone, truth, 0, frames.size());
  const double after = rms_centre_error(smoothed, truth, 0, frames.size());
  EXPECT_GT(before, 0.01);
  EXPECT_LT(after, 0.6 * before) << "alone " << before << " m, smoothed " << after << " m";
  for (const auto& T : smoothed) EXPECT_TRUE(T.matrix().allFinite());
}

TEST(PoseSmoothing, LeavesAConstantVelocityTruthWhereItIs) {
  // Exact observations of a camera at constant velocity, started at the truth: both terms are
  // zero there, so nothing moves (beyond rounding).
  std::vector<Eigen::Isometry3d> truth;
  const auto frames = far_wall(20, 30, 0.0, truth, 0.0);
  const auto smoothed = ds3d::slam::smooth_poses(kK, frames);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_LT((centre(smoothed[i]) - centre(truth[i])).norm(), 1e-6) << "frame " << i;
  }
}

TEST(PoseSmoothing, FixedLostAndUnlinkedFramesKeepTheirPoses) {
  std::vector<Eigen::Isometry3d> truth;
  auto frames = far_wall(30, 25, 0.04, truth);
  frames[5].fixed = true;
  frames[15].valid = false;  // lost: frames 14 and 16 lose the triples through it
  // A 1-s gap before frame 25: frames 24-25 are not linked, so 25 is linked only forwards.
  for (std::size_t i = 25; i < frames.size(); ++i) frames[i].timestamp += 1.0;
  frames[29].valid = false;  // leaves frames 25-28: 25-26-27 and 26-27-28 still link
  const auto smoothed = ds3d::slam::smooth_poses(kK, frames);
  EXPECT_TRUE(smoothed[5].matrix() == frames[5].T_cam_world.matrix());
  EXPECT_TRUE(smoothed[15].matrix() == frames[15].T_cam_world.matrix());
  EXPECT_TRUE(smoothed[29].matrix() == frames[29].T_cam_world.matrix());
  EXPECT_FALSE(smoothed[26].matrix() == frames[26].T_cam_world.matrix());
  // A single frame between two breaks is in no triple.
  frames[13].valid = false;
  const auto again = ds3d::slam::smooth_poses(kK, frames);
  EXPECT_TRUE(again[14].matrix() == frames[14].T_cam_world.matrix());
}

TEST(PoseSmoothing, RejectsBadInputNamingTheParameter) {
  std::vector<Eigen::Isometry3d> truth;
  auto frames = far_wall(5, 10, 0.0, truth);
  const auto message = [&](const std::vector<SmoothingFrame>& f, const PoseSmoothingParams& p) {
    try {
      (void)ds3d::slam::smooth_poses(kK, f, p);
    } catch (const ds3d::InvalidArgument& e) {
      return std::string(e.what());
    }
    return std::string("no throw");
  };
  PoseSmoothingParams p;
  p.acceleration_sigma = 0;
  EXPECT_NE(message(frames, p).find("acceleration_sigma must be > 0 (got 0)"), std::string::npos);
  p = {};
  p.max_gap = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(message(frames, p).find("max_gap"), std::string::npos);
  p = {};
  p.iterations = 0;
  EXPECT_NE(message(frames, p).find("iterations must be >= 1"), std::string::npos);
  auto bad = frames;
  bad[3].timestamp = bad[2].timestamp;
  EXPECT_NE(message(bad, {}).find("smooth_poses: frames[3].timestamp must increase"),
            std::string::npos);
  bad = frames;
  bad[1].observations.pop_back();
  EXPECT_NE(message(bad, {}).find("frames[1] has 10 points but 9 observations"), std::string::npos);
  bad = frames;
  bad[2].T_cam_world.translation().x() = std::numeric_limits<double>::infinity();
  EXPECT_NE(message(bad, {}).find("frames[2].T_cam_world must be finite"), std::string::npos);
  EXPECT_TRUE(ds3d::slam::smooth_poses(kK, {}).empty());
}

}  // namespace
