// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file pose_smoothing.hpp
/// @brief Batch smoothing of a camera trajectory against fixed map points (ds3d::slam).
///
/// Each frame's pose is fixed by its own observations of map points (the pose-only error model of
/// bundle_adjustment.hpp); where those data hardly fix a direction (a far wall seen through a gap
/// in a crowd: a sideways shift and a rotation of shift / depth look alike), the per-frame poses
/// scatter around the true path by centimetres from one frame to the next. smooth_poses() solves
/// for all poses of a sequence at once under an extra Gaussian term per three consecutive frames:
/// the camera centre's acceleration, with a 1-σ of PoseSmoothingParams::acceleration_sigma. Where
/// the observations are strong the term changes next to nothing; where they are weak it takes the
/// constant-velocity path through the neighbours.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "ds3d/detail/abi_guard.hpp"
#include "ds3d/slam/bundle_adjustment.hpp"

namespace ds3d::slam {

/// One frame of the sequence given to smooth_poses(), in time order.
struct SmoothingFrame {
  double timestamp = 0.0;  ///< [s], finite and increasing along the sequence
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();  ///< initial pose
  bool fixed = false;  ///< held constant (e.g. a keyframe already set by bundle adjustment)
  /// false: the frame has no pose (lost); it breaks the sequence into independent pieces.
  bool valid = true;
  std::vector<Eigen::Vector3d> points;    ///< world points the frame observes [m], held fixed
  std::vector<Observation> observations;  ///< one per point
};

/// Parameters of smooth_poses().
struct PoseSmoothingParams {
  double acceleration_sigma = 3.0;  ///< [m/s²] 1-σ of the camera centre's acceleration, > 0
  double max_gap = 0.2;             ///< [s] neighbours farther apart in time are not linked, > 0
  int iterations = 5;               ///< Gauss-Newton iterations, >= 1
  double chi2_mono = 5.991;         ///< Huber δ² of a 2-DoF observation, > 0
  double chi2_stereo = 7.815;       ///< Huber δ² of a 3-DoF observation, > 0
  void validate() const;            ///< throws ds3d::InvalidArgument naming the bad field
};

/// Smooths the poses of `frames` (see the file comment): Gauss-Newton on the sum of every
/// frame's Huber-weighted reprojection χ² (bundle_adjustment.hpp's model) and, for each three
/// consecutive valid frames whose gaps are at most max_gap, |a / acceleration_sigma|², a the
/// camera centre's second divided difference [m/s²]. Fixed frames take part as constant
/// neighbours; a frame that is not valid, or a gap above max_gap, separates the pieces. A step
/// that does not lower the cost is halved (up to 8 times), else the iteration stops.
/// @param k      intrinsics and bf of the observations
/// @param frames the sequence, in time order
/// @param params σ of the acceleration, gap, iterations, Huber thresholds
/// @return one T_cam_world per frame: the smoothed pose, or the input for fixed, invalid and
///         unlinked frames (and for all of them if the solution is not finite)
/// @throws ds3d::InvalidArgument on bad params, a non-finite or decreasing timestamp, a
///         non-finite pose, or points and observations of different sizes (naming the frame).
/// @note O(observations + frames) per iteration (banded sparse Cholesky); deterministic.
[[nodiscard]] std::vector<Eigen::Isometry3d> smooth_poses(const StereoIntrinsics& k,
                                                          const std::vector<SmoothingFrame>& frames,
                                                          const PoseSmoothingParams& params = {});

}  // namespace ds3d::slam
