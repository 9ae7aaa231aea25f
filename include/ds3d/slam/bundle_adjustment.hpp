// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file bundle_adjustment.hpp
/// @brief Pose-only optimisation and local bundle adjustment with Ceres (ds3d::slam).
///
/// The error model is ORB-SLAM2's RGB-D one (Mur-Artal & Tardós 2017, §V): a keypoint with a
/// reliable depth z is a "stereo" observation (u, v, u_r) with the virtual right-camera coordinate
/// u_r = u − bf / z; one without is a monocular (u, v) observation. Residuals are weighted by the
/// keypoint's octave (1/σ² = scale^-2) and wrapped in a Huber loss; an observation is an outlier
/// when its χ² exceeds the 95 % quantile (5.991 for 2 DoF, 7.815 for 3 DoF). Optionally the third
/// row is the disparity bf/z with a σ of its own (Observation::disparity_inv_sigma2).
///
/// Poses are T_cam_world (world → camera). Their Ceres parameter block is 7 doubles
/// `[qx qy qz qw tx ty tz]` on the SO(3)×R³ manifold with the *left* perturbation
/// `T ⊕ (ω, v) = (Exp(ω) R, Exp(ω) t + v)`, so that d(T ⊕ δ · p)/dδ at 0 is `[−[p_c]× | I]`.
/// All Jacobians are analytic (checked against finite differences in tests/slam/).

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ds3d/detail/abi_guard.hpp"

namespace ds3d::slam {

/// A pose increment (ω, v): rotation [rad] then translation [m], as taken by pose_plus().
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// Undistorted pinhole intrinsics plus the virtual stereo baseline times fx (ORB-SLAM2's "bf").
struct StereoIntrinsics {
  double fx = 525.0;  ///< [px], > 0
  double fy = 525.0;  ///< [px], > 0
  double cx = 319.5;  ///< [px]
  double cy = 239.5;  ///< [px]
  double bf = 40.0;   ///< virtual baseline × fx [px·m], > 0 (ORB-SLAM2 uses 40 for TUM)
};

/// The retraction of the pose manifold: `(Exp(ω) R, Exp(ω) t + v)` for delta = (ω, v).
[[nodiscard]] Eigen::Isometry3d pose_plus(const Eigen::Isometry3d& T, const Vector6d& delta);

/// One observation of a 3-D point in an image.
struct Observation {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  ///< undistorted (u, v) [px]
  double u_right = 0.0;     ///< virtual right u [px] (u − bf/z); used only when has_depth
  bool has_depth = false;   ///< true: 3-DoF (u, v, u_right) observation; false: monocular (u, v)
  double inv_sigma2 = 1.0;  ///< information weight 1/σ² of the keypoint's octave, > 0
  /// 0: the third row is ORB-SLAM2's u_right residual, weighted by inv_sigma2. > 0: it is the
  /// disparity residual (u − u_right) − bf/z instead, weighted by this 1/σ_d² [px⁻²]: a depth
  /// sensor's own noise, independent of the keypoint's octave (FrontendConfig::disparity_sigma).
  double disparity_inv_sigma2 = 0.0;
  /// True for a 3-DoF (u, v, u_right) observation: the same as has_depth.
  [[nodiscard]] bool stereo() const noexcept { return has_depth; }
};

/// Weighted reprojection residual of `p_world` seen at `obs` from pose T_cam_world, with its
/// analytic Jacobians. Residual = sqrt(inv_sigma2) · (observed − predicted); rows (u, v[, u_r]);
/// with obs.disparity_inv_sigma2 > 0 the third row is sqrt(disparity_inv_sigma2) · (observed
/// disparity u − u_r − bf/z) instead.
/// @param k        intrinsics (undistorted) and bf
/// @param T_cam_world pose of the camera (world → camera)
/// @param p_world  the point [m, world]
/// @param obs      where it was observed (pixel, u_right when it has depth, weight)
/// @param residual output, 2 or 3 values
/// @param j_pose  if non-null, row-major dim×6 output: d residual / d delta under pose_plus
/// @param j_point if non-null, row-major dim×3 output: d residual / d p_world
/// @return the residual dimension (2 or 3); 0 when the point is not in front of the camera
///         (z ≤ 1e-6), with residual and Jacobians zeroed.
int reprojection_residual(const StereoIntrinsics& k, const Eigen::Isometry3d& T_cam_world,
                          const Eigen::Vector3d& p_world, const Observation& obs, double* residual,
                          double* j_pose, double* j_point);

/// χ² of `p_world` seen at `obs` from T_cam_world: the squared norm of reprojection_residual
/// (weighted, 2 or 3 rows), as the χ² tests of optimize_pose and local_bundle_adjustment use it.
/// @param k           intrinsics (undistorted) and bf
/// @param T_cam_world pose of the camera (world → camera)
/// @param p_world     the point [m, world]
/// @param obs         where it was observed (pixel, u_right when it has depth, weight)
/// @param in_front    if non-null, set to whether the point is in front of the camera
///        (z > 1e-6)
/// @return the χ² (≥ 0, dimensionless); 0 when the point is behind the camera
[[nodiscard]] double reprojection_chi2(const StereoIntrinsics& k,
                                       const Eigen::Isometry3d& T_cam_world,
                                       const Eigen::Vector3d& p_world, const Observation& obs,
                                       bool* in_front = nullptr);

/// χ² thresholds and schedule of the pose-only optimisation (ORB-SLAM2's PoseOptimization).
struct PoseOptimizerParams {
  int rounds = 4;              ///< optimisation rounds with outlier re-classification, >= 1
  int iterations = 10;         ///< Levenberg-Marquardt iterations per round, >= 1
  double chi2_mono = 5.991;    ///< outlier threshold for 2-DoF observations, > 0
  double chi2_stereo = 7.815;  ///< outlier threshold for 3-DoF observations, > 0
  void validate() const;       ///< throws ds3d::InvalidArgument naming the bad field
};

/// Result of optimize_pose.
struct PoseOptimizationResult {
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();  ///< optimised pose
  std::vector<std::uint8_t> inlier;  ///< 1 per observation that passed the final χ² test
  int num_inliers = 0;               ///< count of ones in `inlier`
};

/// A Gaussian prior on the camera centre c = −Rᵀt of optimize_pose: the residual
/// (c − centre) / sigma joins the reprojection terms; the rotation is free. sigma = 0 means no
/// prior.
struct CentrePrior {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< expected camera centre [m, world]
  double sigma = 0.0;  ///< standard deviation [m] of each coordinate, >= 0 (0 = no prior)
  /// Huber threshold of the prior's residual norm, in units of sigma, >= 0 (0 = quadratic):
  /// beyond it the prior's pull stays constant, so matches that clearly contradict it win.
  double huber = 0.0;
};

/// Optimises one camera pose against fixed 3-D points with Ceres: Huber loss (δ² = the χ²
/// threshold), `rounds` rounds after each of which every observation is re-classified by χ²
/// (outliers are excluded from the next round but may come back); the last round has no robust
/// loss. Points behind the camera are outliers.
/// @param k        intrinsics (undistorted) and bf
/// @param initial  starting pose T_cam_world
/// @param points   world points, one per observation
/// @param observations same size as `points`
/// @param params   χ² thresholds, rounds and iterations (PoseOptimizerParams)
/// @param prior    optional prior on the camera centre (CentrePrior; sigma 0 = none); it
///        settles the pose's weakly observed directions (a shift paired with a rotation in front
///        of a far wall) and does not take part in the χ² classification
/// @throws ds3d::InvalidArgument if the sizes differ, params are bad, prior.sigma or
///         prior.huber is negative or not finite, or prior.centre is not finite while sigma > 0.
/// @note O(rounds · iterations · n). Deterministic. With fewer than 3 observations the
///       initial pose is returned unchanged with every observation marked as an outlier.
[[nodiscard]] PoseOptimizationResult optimize_pose(const StereoIntrinsics& k,
                                                   const Eigen::Isometry3d& initial,
                                                   const std::vector<Eigen::Vector3d>& points,
                                                   const std::vector<Observation>& observations,
                                                   const PoseOptimizerParams& params = {},
                                                   const CentrePrior& prior = {});

/// An observation of point `point` in keyframe `keyframe` (indices into the BA input vectors).
struct BaObservation {
  int keyframe = 0;  ///< index into poses
  int point = 0;     ///< index into points
  Observation obs;   ///< where it was seen
};

/// Parameters of local bundle adjustment.
struct LocalBaParams {
  int iterations_first = 5;    ///< iterations before outlier removal, >= 1
  int iterations_second = 10;  ///< iterations after outlier removal, >= 0
  double chi2_mono = 5.991;    ///< outlier threshold, 2 DoF, > 0
  double chi2_stereo = 7.815;  ///< outlier threshold, 3 DoF, > 0
  void validate() const;       ///< throws ds3d::InvalidArgument naming the bad field
};

/// Result of local_bundle_adjustment.
struct LocalBaResult {
  std::vector<Eigen::Isometry3d> poses;  ///< optimised T_cam_world (fixed ones unchanged)
  std::vector<Eigen::Vector3d> points;   ///< optimised points
  std::vector<std::uint8_t> outlier;     ///< 1 per observation rejected by the χ² test
  double initial_cost = 0.0;             ///< Ceres cost before the first solve
  double final_cost = 0.0;               ///< Ceres cost after the last solve
};

/// Local bundle adjustment (ORB-SLAM2's LocalBundleAdjustment) with Ceres: keyframe poses and
/// points are optimised jointly under a Huber loss, poses with `fixed[i]` held constant (at least
/// one must be fixed: the gauge); after `iterations_first` iterations, observations failing the χ²
/// test are removed and the problem is solved again without robust loss.
/// @param k  intrinsics and bf
/// @param poses T_cam_world of each keyframe in the window
/// @param fixed one flag per pose; true = held constant
/// @param points initial world points
/// @param observations links between them; indices must be in range
/// @param params iterations and χ² thresholds (LocalBaParams)
/// @throws ds3d::InvalidArgument on size or index mismatch, no fixed pose, or bad params.
/// @note Uses the Schur complement (points eliminated). Deterministic (single-threaded Ceres).
[[nodiscard]] LocalBaResult local_bundle_adjustment(const StereoIntrinsics& k,
                                                    const std::vector<Eigen::Isometry3d>& poses,
                                                    const std::vector<std::uint8_t>& fixed,
                                                    const std::vector<Eigen::Vector3d>& points,
                                                    const std::vector<BaObservation>& observations,
                                                    const LocalBaParams& params = {});

}  // namespace ds3d::slam
