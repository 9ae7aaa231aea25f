// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Changing a trajectory's world and body frames; the Bonn marker-to-camera transform.
#include "ds3d/eval/trajectory_frames.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "ds3d/eval/trajectory_metrics.hpp"

namespace {

// Eigen's Transform{} is uninitialised.
const Eigen::Isometry3d kI = Eigen::Isometry3d::Identity();

Eigen::Isometry3d pose(double yaw, double pitch, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = t;
  return T;
}

ds3d::Trajectory walk() {
  ds3d::Trajectory traj;
  for (int i = 0; i < 30; ++i) {
    const double s = 0.1 * i;
    traj.push_back({1.0 + 0.033 * i,
                    pose(0.3 * s, 0.1 * std::sin(s), Eigen::Vector3d(std::cos(s), 0.5 * s, 0.2))});
  }
  return traj;
}

TEST(TrajectoryFrames, TransformMultipliesEveryPose) {
  const ds3d::Trajectory traj = walk();
  const Eigen::Isometry3d A = pose(0.7, -0.2, Eigen::Vector3d(1, 2, 3));
  const Eigen::Isometry3d B = pose(-1.1, 0.4, Eigen::Vector3d(0.01, -0.02, 0.03));
  const ds3d::Trajectory out = ds3d::transform_trajectory(traj, A, B);
  ASSERT_EQ(out.size(), traj.size());
  for (std::size_t i = 0; i < traj.size(); ++i) {
    EXPECT_EQ(out[i].timestamp, traj[i].timestamp);
    EXPECT_TRUE(out[i].T_world_cam.isApprox(A * traj[i].T_world_cam * B, 1e-12));
  }
  // A world change alone leaves the ATE (SE(3)-aligned) at zero; a lever arm does not.
  EXPECT_LT(ds3d::evaluate_ate(traj, ds3d::transform_trajectory(traj, A, kI)).rmse, 1e-9);
  EXPECT_GT(ds3d::evaluate_ate(traj, ds3d::transform_trajectory(traj, kI, B)).rmse, 1e-3);
}

TEST(TrajectoryFrames, RefusesTransformsThatAreNotRigid) {
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 1.05;
  Eigen::Isometry3d mirror = Eigen::Isometry3d::Identity();
  mirror.linear()(0, 0) = -1.0;
  Eigen::Isometry3d nan = Eigen::Isometry3d::Identity();
  nan.translation().x() = std::numeric_limits<double>::quiet_NaN();
  const auto message = [](const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    try {
      (void)ds3d::transform_trajectory(walk(), a, b);
    } catch (const ds3d::InvalidArgument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message(scaled, kI).find("ds3d::transform_trajectory: world_from must be a rigid"),
            std::string::npos);
  EXPECT_NE(message(kI, mirror).find("body_to must be a rigid transform"), std::string::npos);
  EXPECT_NE(message(kI, nan).find("body_to must be finite"), std::string::npos);
}

// camera = T_ros⁻¹ · T_gt · T_ros · T_m: at the identity marker pose the camera pose is T_m
// itself (orthonormalised), and in general the dataset's formula with that rotation.
TEST(TrajectoryFrames, BonnMarkerToCamera) {
  const ds3d::Trajectory id = ds3d::bonn_marker_to_camera({{5.0, Eigen::Isometry3d::Identity()}});
  ASSERT_EQ(id.size(), 1U);
  const Eigen::Matrix3d R = id[0].T_world_cam.linear();
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_TRUE(id[0].T_world_cam.translation().isApprox(Eigen::Vector3d(0.0113, -0.0098, 0.0111)));
  Eigen::Matrix3d m;
  m << 1.0157, 0.1828, -0.2389, 0.0009, -0.8431, -0.6413, -0.3009, 0.6147, -0.8085;
  EXPECT_LT((m / ds3d::kBonnDepthScaleFactor - R).cwiseAbs().maxCoeff(), 2e-4);

  Eigen::Matrix4d ros;
  ros << -1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 1;
  const Eigen::Isometry3d T_ros(ros);
  const ds3d::Trajectory traj = walk();
  const ds3d::Trajectory cam = ds3d::bonn_marker_to_camera(traj);
  for (std::size_t i = 0; i < traj.size(); ++i) {
    const Eigen::Isometry3d want =
        T_ros.inverse() * traj[i].T_world_cam * T_ros * id[0].T_world_cam;
    EXPECT_TRUE(cam[i].T_world_cam.isApprox(want, 1e-12)) << i;
  }
}

}  // namespace
