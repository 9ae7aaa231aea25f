// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file radius_outlier.hpp
/// @brief Radius outlier removal (3DS-SLAM §III-B): keep points with at least k neighbours in R.
///
/// The neighbour count of point i is `#{ j != i, j finite : |p_i - p_j|^2 <= R^2 }`, computed in
/// double from the float inputs; an exact duplicate (distance 0) is a neighbour, the point itself
/// is not. Point i is kept iff its count is >= min_neighbors. This is Open3D's
/// `RemoveRadiusOutliers(nb_points = k, R)` and PCL's `RadiusOutlierRemoval` with
/// `setMinNeighborsInRadius(k)` except at exact ties (both count the query point and test > k;
/// Open3D uses `d^2 < R^2`). Non-finite points are never kept and are nobody's neighbour.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ds3d/cloud.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// Neighbour search used by remove_radius_outliers(); both give identical kept sets.
enum class RadiusSearch : std::uint8_t {
  kGrid,    ///< uniform grid of cell edge R, 27 cells per query (default, faster)
  kKdTree,  ///< nanoflann KD-tree over the cloud's traits (radius search, early exit at k)
};

/// Parameters of remove_radius_outliers().
struct RadiusOutlierParams {
  double radius = 0.05;                        ///< search radius R [m], finite and > 0
  std::uint32_t min_neighbors = 16;            ///< k: keep iff >= k other points lie within R
  NonFinite on_non_finite = NonFinite::kSkip;  ///< kSkip: never kept, counted; kThrow: throw
  int num_threads = 1;                         ///< 0 = all hardware threads, < 0 is invalid
  RadiusSearch search = RadiusSearch::kGrid;   ///< neighbour search (same result either way)
  /// Throws ds3d::InvalidArgument naming the bad field and value.
  void validate() const;
};

/// Output of remove_radius_outliers().
struct RadiusOutlierResult {
  std::vector<std::uint32_t> kept;  ///< input indices of kept points, ascending
  std::size_t num_non_finite = 0;   ///< input points skipped as non-finite
};

/// Radius outlier removal over any PointCloud.
/// @param cloud  points [m]; non-finite ones are ignored (never kept, nobody's neighbour).
/// @param params radius R [m], min_neighbors k, non-finite policy and threads.
/// @return ascending input indices of the points with >= k other finite points within R.
/// @throws ds3d::InvalidArgument on bad params, on a non-finite point under kThrow, when the
///         extent of the cloud divided by R overflows 64-bit grid keys, or on clouds of 2^32 - 1
///         points or more.
/// @note Uses a uniform neighbour grid with cells of edge R (a point's neighbours lie in the 27
///       cells around it), visited own cell first, and stops counting at k. Expected O(n·k)
///       time for surface-like data, O(n) memory; exact (double distances); output identical
///       for every num_threads. With min_neighbors = 0 every finite point is kept.
template <PointCloud C>
[[nodiscard]] RadiusOutlierResult remove_radius_outliers(const C& cloud,
                                                         const RadiusOutlierParams& params = {});

/// Overload for a row-major N×3 float map (numpy float32, no copy).
[[nodiscard]] inline RadiusOutlierResult remove_radius_outliers(
    Eigen::Ref<const Points3f> xyz, const RadiusOutlierParams& params = {}) {
  return remove_radius_outliers<Eigen::Ref<const Points3f>>(xyz, params);
}

}  // namespace ds3d

#include "ds3d/detail/radius_outlier_impl.hpp"
