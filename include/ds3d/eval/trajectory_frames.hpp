// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file trajectory_frames.hpp
/// @brief Changing the world and body frames of a trajectory, and the Bonn RGB-D Dynamic
/// dataset's marker-to-camera transform.
///
/// A ground truth recorded by motion capture gives the pose of a marker body, not of the camera.
/// `transform_trajectory(traj, A, B)` maps every camera-to-world pose T to A · T · B: A changes
/// the world frame, B the body frame (body to camera).

#include <utility>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"

namespace ds3d {

namespace detail {

/// Throws InvalidArgument naming `fn` and `param` unless `T` is finite and rigid (rotation block
/// orthonormal to 1e-6 with determinant +1, last row 0 0 0 1).
inline void check_rigid(const Eigen::Isometry3d& T, const char* fn, const char* param) {
  const Eigen::Matrix4d& m = T.matrix();
  DS3D_CHECK(m.allFinite(), fn, ": ", param, " must be finite");
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  const double off = orthonormality_error(R);
  DS3D_CHECK(off <= 1e-6 && R.determinant() > 0.0, fn, ": ", param,
             " must be a rigid transform (rotation block off orthonormal by ", off,
             ", determinant ", R.determinant(), ")");
  DS3D_CHECK(m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)), fn, ": ", param,
             " must have a last row 0 0 0 1");
}

}  // namespace detail

/// Every pose T_world_cam replaced by `world_from · T_world_cam · body_to`; timestamps and order
/// kept.
/// @param traj camera-to-world poses (any order)
/// @param world_from rigid transform from the old world frame to the new one
/// @param body_to rigid transform from the new body (camera) frame to the old body frame
/// @throws ds3d::InvalidArgument when world_from or body_to is not finite and rigid
[[nodiscard]] inline Trajectory transform_trajectory(Trajectory traj,
                                                     const Eigen::Isometry3d& world_from,
                                                     const Eigen::Isometry3d& body_to) {
  constexpr const char* kFn = "ds3d::transform_trajectory";
  detail::check_rigid(world_from, kFn, "world_from");
  detail::check_rigid(body_to, kFn, "body_to");
  for (TimedPose& p : traj) p.T_world_cam = world_from * p.T_world_cam * body_to;
  return traj;
}

/// The scale of the Bonn RGB-D Dynamic dataset's camera transform T_m: the factor by which points
/// measured by its sensor (depth read at 5000 units per metre) must be multiplied to be metric in
/// the motion-capture frame. Depth read at 5000 / 1.0593 ≈ 4720 units per metre is metric.
inline constexpr double kBonnDepthScaleFactor = 1.0593;

/// The Bonn RGB-D Dynamic dataset's fixed transforms applied to its `groundtruth.txt` (poses of
/// the motion-capture marker): camera = T_ros⁻¹ · T_gt · T_ros · T_m, with
/// T_ros = [[-1,0,0,0],[0,0,1,0],[0,1,0,0],[0,0,0,1]] and T_m as the dataset publishes it. The
/// rotation block of T_m is a rotation times kBonnDepthScaleFactor; a pose keeps only the
/// rotation (nearest orthonormal matrix) and T_m's translation (the marker-to-camera lever arm,
/// about 2 cm). An ATE against the raw file (as the ORB-SLAM family of papers reports it) and one
/// against these poses differ by that lever arm; the alignment absorbs the axes.
/// @param marker the raw ground truth (camera-to-world of the marker)
[[nodiscard]] inline Trajectory bonn_marker_to_camera(Trajectory marker) {
  Eigen::Matrix4d ros;
  ros << -1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 1;
  Eigen::Matrix4d tm;
  tm << 1.0157, 0.1828, -0.2389, 0.0113,  //
      0.0009, -0.8431, -0.6413, -0.0098,  //
      -0.3009, 0.6147, -0.8085, 0.0111,   //
      0, 0, 0, 1;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(tm.topLeftCorner<3, 3>(),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Isometry3d body = Eigen::Isometry3d::Identity();
  body.linear() = svd.matrixU() * svd.matrixV().transpose();  // det +1 for this T_m
  body.translation() = tm.topRightCorner<3, 1>();
  const Eigen::Isometry3d T_ros(ros);
  return transform_trajectory(std::move(marker), T_ros.inverse(), T_ros * body);
}

}  // namespace ds3d
