// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file ransac_plane.hpp
/// @brief RANSAC plane segmentation (Fischler & Bolles 1981) with least-squares refit and inlier
///        re-selection; used for ground removal (3DS-SLAM §III-B).
///
/// The plane is `a x + b y + c z + d = 0` with `|(a, b, c)| = 1`; a point is an inlier iff
/// `|a x + b y + c z + d| < t` (strict, as Open3D and PCL). Hypotheses come from random triples
/// of finite points; the one with most inliers wins (ties: the earliest iteration). It is then
/// locally optimised (LO-RANSAC, Chum, Matas & Kittler 2003; iterated least squares as in LO+,
/// Lebeda, Matas & Chum 2012): the points within 3t of the plane are fitted by least squares
/// (smallest eigenvector of their covariance) and the inliers re-selected, a round being kept only
/// if it does not lose inliers; so the returned inliers are exactly the inliers of the returned
/// plane (Open3D 0.16 skips the re-selection). An optional normal prior restricts hypotheses to
/// planes whose normal lies within an angle of a given up vector, so that the floor is chosen
/// rather than a larger wall.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ds3d/cloud.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// Parameters of ransac_plane().
struct RansacPlaneParams {
  double distance_threshold = 0.01;     ///< t [m], finite and > 0; inlier iff |distance| < t
  std::uint32_t max_iterations = 1000;  ///< number of random triples, >= 1
  /// Early stop once `1 - (1 - w^3)^iterations >= confidence` (w: best inlier fraction so far),
  /// in [0, 1]; 1 disables the early stop (exactly max_iterations hypotheses are scored).
  double confidence = 0.999;
  std::uint64_t seed = 0;  ///< same seed, same input: same output (for any num_threads)
  /// Optional normal prior: when non-zero, only planes whose normal is within `max_angle_deg` of
  /// ±normal_prior are accepted, and the returned normal points along normal_prior.
  Eigen::Vector3d normal_prior = Eigen::Vector3d::Zero();
  double max_angle_deg = 20.0;  ///< tolerance of the normal prior [deg], in (0, 90]
  /// With a normal prior: also require the origin (the sensor, for camera-frame clouds) to lie on
  /// the +normal_prior side of the plane, so a floor below the camera is chosen, not a ceiling.
  bool origin_above = false;
  /// Local-optimisation rounds after RANSAC (least-squares fit of the points within 3t, then
  /// re-selection of the < t inliers; 0 = return the best hypothesis). Rounds stop early when one
  /// changes nothing or would lose inliers.
  std::uint32_t refine_iterations = 3;
  NonFinite on_non_finite = NonFinite::kSkip;  ///< kSkip: never inliers, counted; kThrow: throw
  int num_threads = 1;                         ///< 0 = all hardware threads, < 0 is invalid
  /// Throws ds3d::InvalidArgument naming the bad field and value.
  void validate() const;
};

/// ransac_plane() scores hypotheses on `num_threads` threads only for clouds of at least this
/// many finite points; smaller clouds score a batch faster than its threads start, and run on
/// one (2-vCPU AMD EPYC, 1,000 hypotheses: 5,000 points 0.65 ms on one thread against 4.6 ms on
/// two, 50,000 points 6.4 against 8.8 ms, 100,000 points equal; docs/benchmarks.md).
inline constexpr std::size_t kRansacParallelMinPoints = 100000;

/// Output of ransac_plane().
struct RansacPlaneResult {
  bool found = false;  ///< false: fewer than 3 finite points, or every triple was degenerate
                       ///< or violated the normal prior
  /// (a, b, c, d) with unit (a, b, c). Sign: along normal_prior if given, else the
  /// largest-magnitude normal component is positive. Zero when !found.
  Eigen::Vector4d plane = Eigen::Vector4d::Zero();
  std::vector<std::uint32_t> inliers;  ///< ascending input indices: |distance| < t (in double)
  std::uint32_t iterations = 0;        ///< hypotheses drawn before stopping
  std::size_t num_non_finite = 0;      ///< input points skipped as non-finite
};

/// Fits the dominant plane of `cloud` with RANSAC.
/// @param cloud  points [m]; non-finite ones are ignored and counted.
/// @param params threshold [m], iterations, confidence, seed, optional normal prior, threads.
/// @return found flag, unit plane, its inliers (ascending input indices) and iterations used.
/// @throws ds3d::InvalidArgument on bad params, on a non-finite point under kThrow, or on clouds
///         of 2^32 - 1 points or more. "No plane" is `found = false`, not an exception.
/// @note O(iterations · n) time, O(n) memory. Inliers are counted in float on structure-of-arrays
///       data (vectorised) for scoring; the final inliers are selected in double. Each iteration's
///       triple depends only on (seed, iteration), and hypotheses are scored in batches reduced in
///       iteration order, so the output is identical for every num_threads.
template <PointCloud C>
[[nodiscard]] RansacPlaneResult ransac_plane(const C& cloud, const RansacPlaneParams& params = {});

/// Overload for a row-major N×3 float map (numpy float32, no copy).
[[nodiscard]] inline RansacPlaneResult ransac_plane(Eigen::Ref<const Points3f> xyz,
                                                    const RansacPlaneParams& params = {}) {
  return ransac_plane<Eigen::Ref<const Points3f>>(xyz, params);
}

}  // namespace ds3d

#include "ds3d/detail/ransac_plane_impl.hpp"
