// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/bundle_adjustment.hpp"

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "ds3d/errors.hpp"
#include "support/synthetic.hpp"

namespace {

using ds3d::slam::BaObservation;
using ds3d::slam::Observation;
using ds3d::slam::StereoIntrinsics;
using ds3d::slam::Vector6d;

const StereoIntrinsics kK{517.3, 516.5, 318.6, 255.3, 40.0};

Eigen::Isometry3d make_pose(const Eigen::Vector3d& rotvec, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(rotvec.norm(), rotvec.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// Perfect observation of p from T (optionally with depth), before noise.
Observation observe(const Eigen::Isometry3d& T_cw, const Eigen::Vector3d& p, bool stereo) {
  const Eigen::Vector3d pc = T_cw * p;
  Observation o;
  o.pixel = {kK.fx * pc.x() / pc.z() + kK.cx, kK.fy * pc.y() / pc.z() + kK.cy};
  o.u_right = stereo ? o.pixel.x() - kK.bf / pc.z() : 0.0;
  o.has_depth = stereo;
  o.inv_sigma2 = 1.0 / (1.2 * 1.2);
  return o;
}

double rotation_error_rad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

// The three residual forms: monocular, ORB-SLAM2's u_right, and the disparity term.
enum class Form { kMono, kURight, kDisparity };

class JacobianTest : public ::testing::TestWithParam<Form> {};

TEST_P(JacobianTest, AnalyticMatchesCentralDifferences) {
  const bool stereo = GetParam() != Form::kMono;
  ds3d::test::Rng rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Isometry3d T =
        make_pose({rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5)},
                  {rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)});
    // A point 1-4 m in front of the camera, expressed in the world.
    const Eigen::Vector3d pc(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(1, 4));
    const Eigen::Vector3d pw = T.inverse() * pc;
    Observation obs = observe(T, pw, stereo);
    if (GetParam() == Form::kDisparity) obs.disparity_inv_sigma2 = 1.0 / (0.2 * 0.2);
    obs.pixel += Eigen::Vector2d(rng.normal(), rng.normal()) * 3.0;  // non-zero residual
    obs.u_right += rng.normal() * 2.0;
    double r[3];
    double jp[18];
    double jx[9];
    const int dim = ds3d::slam::reprojection_residual(kK, T, pw, obs, r, jp, jx);
    ASSERT_EQ(dim, stereo ? 3 : 2);
    constexpr double h = 1e-6;
    for (int c = 0; c < 6; ++c) {
      Vector6d d = Vector6d::Zero();
      d[c] = h;
      double rp[3];
      double rm[3];
      ds3d::slam::reprojection_residual(kK, ds3d::slam::pose_plus(T, d), pw, obs, rp, nullptr,
                                        nullptr);
      ds3d::slam::reprojection_residual(kK, ds3d::slam::pose_plus(T, -d), pw, obs, rm, nullptr,
                                        nullptr);
      for (int row = 0; row < dim; ++row) {
        const double numeric = (rp[row] - rm[row]) / (2 * h);
        EXPECT_NEAR(jp[row * 6 + c], numeric, 1e-4 * std::max(1.0, std::abs(numeric)))
            << "pose row " << row << " col " << c;
      }
    }
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      d[c] = h;
      double rp[3];
      double rm[3];
      ds3d::slam::reprojection_residual(kK, T, pw + d, obs, rp, nullptr, nullptr);
      ds3d::slam::reprojection_residual(kK, T, pw - d, obs, rm, nullptr, nullptr);
      for (int row = 0; row < dim; ++row) {
        const double numeric = (rp[row] - rm[row]) / (2 * h);
        EXPECT_NEAR(jx[row * 3 + c], numeric, 1e-4 * std::max(1.0, std::abs(numeric)))
            << "point row " << row << " col " << c;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(MonoStereoDisparity, JacobianTest,
                         ::testing::Values(Form::kMono, Form::kURight, Form::kDisparity));

TEST(ReprojectionResidual, DisparityRowIsTheDisparityErrorOverItsSigma) {
  const Eigen::Isometry3d T = make_pose({0.1, -0.2, 0.05}, {0.3, -0.1, 0.2});
  const Eigen::Vector3d pc(0.4, -0.3, 2.5);
  const Eigen::Vector3d pw = T.inverse() * pc;
  Observation obs = observe(T, pw, true);
  obs.pixel.x() += 1.5;  // the u row and the measured disparity u − u_right both change
  obs.u_right += 1.25;   // measured disparity = bf/z + 0.25 px
  double r_ur[3];
  ASSERT_EQ(ds3d::slam::reprojection_residual(kK, T, pw, obs, r_ur, nullptr, nullptr), 3);
  obs.disparity_inv_sigma2 = 1.0 / (0.1 * 0.1);
  double r[3];
  ASSERT_EQ(ds3d::slam::reprojection_residual(kK, T, pw, obs, r, nullptr, nullptr), 3);
  EXPECT_DOUBLE_EQ(r[0], r_ur[0]);
  EXPECT_DOUBLE_EQ(r[1], r_ur[1]);
  EXPECT_NEAR(r[2], 0.25 / 0.1, 1e-9);     // σ_d = 0.1 px
  EXPECT_NEAR(r_ur[2], 1.25 / 1.2, 1e-9);  // the u_right error over the octave σ
  EXPECT_NEAR(ds3d::slam::reprojection_chi2(kK, T, pw, obs), r[0] * r[0] + r[1] * r[1] + 6.25,
              1e-9);
}

TEST(ReprojectionChi2, IsTheSquaredResidualAndFlagsPointsBehind) {
  const Eigen::Isometry3d T = make_pose({0.1, -0.2, 0.05}, {0.3, -0.1, 0.2});
  const Eigen::Vector3d pw = T.inverse() * Eigen::Vector3d(0.4, -0.3, 2.5);
  for (const bool stereo : {false, true}) {
    Observation obs = observe(T, pw, stereo);
    obs.pixel += Eigen::Vector2d(1.5, -2.0);
    double r[3] = {0, 0, 0};
    const int dim = ds3d::slam::reprojection_residual(kK, T, pw, obs, r, nullptr, nullptr);
    double expected = 0;
    for (int i = 0; i < dim; ++i) expected += r[i] * r[i];
    bool front = false;
    EXPECT_DOUBLE_EQ(ds3d::slam::reprojection_chi2(kK, T, pw, obs, &front), expected);
    EXPECT_TRUE(front);
    EXPECT_GT(expected, 1.0);
  }
  bool front = true;
  const Eigen::Vector3d behind = T.inverse() * Eigen::Vector3d(0.0, 0.0, -1.0);
  EXPECT_EQ(ds3d::slam::reprojection_chi2(kK, T, behind, observe(T, pw, true), &front), 0.0);
  EXPECT_FALSE(front);
  EXPECT_EQ(ds3d::slam::reprojection_chi2(kK, T, pw, observe(T, pw, false)), 0.0);
}

TEST(ReprojectionResidual, PointBehindCameraGivesZeroDimension) {
  double r[3] = {1, 1, 1};
  double j[18];
  Observation o;
  o.u_right = 10.0;
  o.has_depth = true;
  EXPECT_EQ(ds3d::slam::reprojection_residual(kK, Eigen::Isometry3d::Identity(), {0, 0, -1}, o, r,
                                              j, nullptr),
            0);
  EXPECT_EQ(r[0], 0.0);
  EXPECT_EQ(r[2], 0.0);
}

TEST(PosePlus, ZeroDeltaIsIdentityAndStaysOrthonormal) {
  const Eigen::Isometry3d T = make_pose({0.1, -0.2, 0.3}, {1, 2, 3});
  EXPECT_TRUE(ds3d::slam::pose_plus(T, Vector6d::Zero()).isApprox(T, 1e-12));
  Eigen::Isometry3d U = T;
  Vector6d d;
  d << 0.3, 0.2, -0.1, 0.5, 0.1, 0.2;
  for (int i = 0; i < 1000; ++i) U = ds3d::slam::pose_plus(U, d);
  EXPECT_NEAR((U.linear().transpose() * U.linear() - Eigen::Matrix3d::Identity()).norm(), 0.0,
              1e-9);
}

struct Scene {
  Eigen::Isometry3d truth;
  std::vector<Eigen::Vector3d> points;
  std::vector<Observation> obs;
  std::vector<bool> is_outlier;
};

Scene make_scene(std::uint64_t seed, int n, double outlier_fraction) {
  ds3d::test::Rng rng(seed);
  Scene s;
  s.truth = make_pose({0.05, -0.1, 0.08}, {0.2, -0.1, 0.3});
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d pc(rng.uniform(-1.5, 1.5), rng.uniform(-1, 1), rng.uniform(1, 5));
    const Eigen::Vector3d pw = s.truth.inverse() * pc;
    Observation o = observe(s.truth, pw, i % 3 != 0);
    o.pixel += Eigen::Vector2d(rng.normal(), rng.normal()) * 0.5;
    if (o.stereo()) o.u_right += rng.normal() * 0.5;
    const bool outlier = rng.uniform() < outlier_fraction;
    if (outlier) o.pixel += Eigen::Vector2d(rng.uniform(20, 60), rng.uniform(-60, -20));
    s.points.push_back(pw);
    s.obs.push_back(o);
    s.is_outlier.push_back(outlier);
  }
  return s;
}

TEST(OptimizePose, RecoversPoseAndFlagsOutliers) {
  const Scene s = make_scene(3, 300, 0.2);
  // Start 5 cm and ~3 degrees away.
  const Eigen::Isometry3d init = ds3d::slam::pose_plus(
      s.truth, (Vector6d() << 0.03, -0.02, 0.04, 0.05, -0.03, 0.02).finished());
  const auto r = ds3d::slam::optimize_pose(kK, init, s.points, s.obs);
  EXPECT_LT((r.T_cam_world.translation() - s.truth.translation()).norm(), 0.005);
  EXPECT_LT(rotation_error_rad(r.T_cam_world, s.truth), 0.002);
  int flagged_outliers = 0;
  int n_outliers = 0;
  int kept_inliers = 0;
  for (std::size_t i = 0; i < s.obs.size(); ++i) {
    n_outliers += s.is_outlier[i] ? 1 : 0;
    if (s.is_outlier[i] && r.inlier[i] == 0) ++flagged_outliers;
    if (!s.is_outlier[i] && r.inlier[i] != 0) ++kept_inliers;
  }
  EXPECT_EQ(flagged_outliers, n_outliers);
  EXPECT_GT(kept_inliers, static_cast<int>(0.9 * (300 - n_outliers)));
  EXPECT_EQ(r.num_inliers, kept_inliers);
  EXPECT_TRUE(r.T_cam_world.matrix().allFinite());
}

TEST(OptimizePose, TooFewObservationsReturnsInitial) {
  const Scene s = make_scene(4, 2, 0.0);
  const auto r = ds3d::slam::optimize_pose(kK, s.truth, s.points, s.obs);
  EXPECT_TRUE(r.T_cam_world.isApprox(s.truth));
  EXPECT_EQ(r.num_inliers, 0);
}

TEST(OptimizePose, RejectsBadInput) {
  const Scene s = make_scene(5, 10, 0.0);
  std::vector<Eigen::Vector3d> fewer(s.points.begin(), s.points.end() - 1);
  EXPECT_THROW((void)ds3d::slam::optimize_pose(kK, s.truth, fewer, s.obs), ds3d::InvalidArgument);
  ds3d::slam::PoseOptimizerParams p;
  p.rounds = 0;
  EXPECT_THROW((void)ds3d::slam::optimize_pose(kK, s.truth, s.points, s.obs, p),
               ds3d::InvalidArgument);
  p = {};
  p.chi2_mono = std::nan("");
  EXPECT_THROW((void)ds3d::slam::optimize_pose(kK, s.truth, s.points, s.obs, p),
               ds3d::InvalidArgument);
}

// A wall 4 m in front of the camera seen without depth: a sideways shift of the camera and a
// rotation of shift / 4 m move its image alike, so the matches leave that direction loose.
struct FarWall {
  Eigen::Isometry3d truth = make_pose({0.01, -0.02, 0.005}, {0.1, -0.05, 0.2});
  std::vector<Eigen::Vector3d> points;
  std::vector<Observation> obs;
};

FarWall make_far_wall(int seed) {
  ds3d::test::Rng rng(static_cast<std::uint64_t>(seed));
  FarWall w;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d pc(rng.uniform(-1.5, 1.5), rng.uniform(-1.0, 1.0), rng.uniform(3.9, 4.1));
    const Eigen::Vector3d pw = w.truth.inverse() * pc;
    Observation o = observe(w.truth, pw, false);
    o.pixel += Eigen::Vector2d(rng.normal(), rng.normal());
    w.points.push_back(pw);
    w.obs.push_back(o);
  }
  return w;
}

Eigen::Vector3d centre(const Eigen::Isometry3d& T_cw) { return T_cw.inverse().translation(); }

TEST(OptimizePose, CentrePriorSettlesTheCentreAndLeavesTheRotationFree) {
  const FarWall w = make_far_wall(21);
  const auto free = ds3d::slam::optimize_pose(kK, w.truth, w.points, w.obs);
  // A loose prior changes nothing; a tight one puts the centre where it says, 3 cm sideways,
  // and the rotation takes up the shift: every observation stays an inlier.
  ds3d::slam::CentrePrior prior{centre(w.truth) + Eigen::Vector3d(0.03, 0.0, 0.0), 100.0};
  const auto loose = ds3d::slam::optimize_pose(kK, w.truth, w.points, w.obs, {}, prior);
  EXPECT_LT((centre(loose.T_cam_world) - centre(free.T_cam_world)).norm(), 1e-6);
  prior.sigma = 1e-4;
  const auto tight = ds3d::slam::optimize_pose(kK, w.truth, w.points, w.obs, {}, prior);
  EXPECT_LT((centre(tight.T_cam_world) - prior.centre).norm(), 1e-3);
  EXPECT_GT(rotation_error_rad(tight.T_cam_world, w.truth), 0.005);  // ≈ 0.03 m / 4 m
  EXPECT_GE(tight.num_inliers, free.num_inliers - 5);
  EXPECT_TRUE(tight.T_cam_world.matrix().allFinite());
}

TEST(OptimizePose, RejectsABadCentrePrior) {
  const FarWall w = make_far_wall(22);
  for (const double sigma : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    const ds3d::slam::CentrePrior prior{Eigen::Vector3d::Zero(), sigma};
    EXPECT_THROW((void)ds3d::slam::optimize_pose(kK, w.truth, w.points, w.obs, {}, prior),
                 ds3d::InvalidArgument)
        << sigma;
  }
  const ds3d::slam::CentrePrior nan_centre{Eigen::Vector3d(0, std::nan(""), 0), 0.01};
  EXPECT_THROW((void)ds3d::slam::optimize_pose(kK, w.truth, w.points, w.obs, {}, nan_centre),
               ds3d::InvalidArgument);
  // sigma 0 is no prior, whatever the centre.
  const ds3d::slam::CentrePrior off{Eigen::Vector3d(0, std::nan(""), 0), 0.0};
  EXPECT_NO_THROW((void)ds3d::slam::optimize_pose(kK, w.truth, w.points, w.obs, {}, off));
}

TEST(LocalBundleAdjustment, ReducesErrorWithFixedGauge) {
  ds3d::test::Rng rng(11);
  std::vector<Eigen::Isometry3d> truth;
  for (int i = 0; i < 5; ++i)
    truth.push_back(make_pose({0.0, 0.02 * i + 1e-9, 0.0}, {-0.1 * i, 0.0, 0.0}));
  std::vector<Eigen::Vector3d> pts_true;
  for (int j = 0; j < 200; ++j)
    pts_true.emplace_back(rng.uniform(-1.5, 1.5), rng.uniform(-1, 1), rng.uniform(2, 5));
  std::vector<BaObservation> obs;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 200; ++j) {
      BaObservation o;
      o.keyframe = i;
      o.point = j;
      o.obs =
          observe(truth[static_cast<std::size_t>(i)], pts_true[static_cast<std::size_t>(j)], true);
      o.obs.pixel += Eigen::Vector2d(rng.normal(), rng.normal()) * 0.3;
      o.obs.u_right += rng.normal() * 0.3;
      obs.push_back(o);
    }
  }
  obs[5].obs.pixel.x() += 80.0;  // one gross outlier
  std::vector<Eigen::Isometry3d> init = truth;
  std::vector<std::uint8_t> fixed{1, 0, 0, 0, 0};
  for (std::size_t i = 1; i < init.size(); ++i) {
    init[i] = ds3d::slam::pose_plus(
        truth[i], (Vector6d() << 0.01, -0.01, 0.005, 0.03, 0.02, -0.02).finished());
  }
  std::vector<Eigen::Vector3d> pts = pts_true;
  for (auto& p : pts) p += Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()) * 0.02;
  const auto r = ds3d::slam::local_bundle_adjustment(kK, init, fixed, pts, obs);
  EXPECT_TRUE(r.poses[0].isApprox(init[0]));  // fixed stays put
  for (std::size_t i = 1; i < truth.size(); ++i) {
    EXPECT_LT((r.poses[i].translation() - truth[i].translation()).norm(), 0.005)
        << "keyframe " << i;
    EXPECT_LT((init[i].translation() - truth[i].translation()).norm(), 0.1);
  }
  EXPECT_LT(r.final_cost, r.initial_cost);
  EXPECT_EQ(r.outlier[5], 1);
  for (const auto& p : r.points) EXPECT_TRUE(p.allFinite());
}

TEST(LocalBundleAdjustment, RejectsBadInput) {
  const std::vector<Eigen::Isometry3d> poses(2, Eigen::Isometry3d::Identity());
  const std::vector<Eigen::Vector3d> pts{{0, 0, 2}};
  std::vector<BaObservation> obs(1);
  EXPECT_THROW((void)ds3d::slam::local_bundle_adjustment(kK, poses, {0, 0}, pts, obs),
               ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::slam::local_bundle_adjustment(kK, poses, {1}, pts, obs),
               ds3d::InvalidArgument);
  obs[0].point = 3;
  EXPECT_THROW((void)ds3d::slam::local_bundle_adjustment(kK, poses, {1, 0}, pts, obs),
               ds3d::InvalidArgument);
  obs[0].point = 0;
  obs[0].keyframe = -1;
  EXPECT_THROW((void)ds3d::slam::local_bundle_adjustment(kK, poses, {1, 0}, pts, obs),
               ds3d::InvalidArgument);
}

}  // namespace
