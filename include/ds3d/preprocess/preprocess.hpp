// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file preprocess.hpp
/// @brief The per-frame detector input of 3DS-SLAM §III-B in one call: depth → cloud → voxel
///        centroids → ground-plane removal → radius outlier removal (XYZ only).
///
/// Every stage is the public component of the same name (rgbd.hpp, voxel_grid.hpp,
/// ransac_plane.hpp, radius_outlier.hpp); this header only composes them and keeps, for every
/// output point, the voxel it came from and the pixel of that voxel's representative point, so
/// detections can be mapped back to pixels and ORB keypoints.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/preprocess/radius_outlier.hpp"
#include "ds3d/preprocess/ransac_plane.hpp"
#include "ds3d/preprocess/rgbd.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"

namespace ds3d {

/// Parameters of preprocess(): one struct for the whole chain.
struct PreprocessParams {
  /// Back-projection; default stride 2 (every other pixel and row: at 1-5 m that is 4-20 mm
  /// apart, far below the leaf, and 4x less work).
  DepthToPointsParams depth = make_default_depth();
  /// Down-sampling; default leaf 0.1 m, which leaves ~4k points of a 640x480 indoor frame.
  VoxelGridParams voxel = make_default_voxel();
  bool remove_ground = true;  ///< run RANSAC on the centroids and drop the plane's inliers
  /// Ground plane search on the centroids. Default prior: camera y axis points down, so "up" is
  /// -y; the floor must be within 30° of it and below the camera (origin_above), so a ceiling
  /// is never taken for the ground (set normal_prior to zero to accept any plane).
  RansacPlaneParams ground = make_default_ground();
  /// Minimum inliers (fraction of the centroids) for the plane to count as ground, in [0, 1].
  double min_ground_fraction = 0.05;
  bool remove_outliers = true;  ///< run radius outlier removal on the remaining centroids
  RadiusOutlierParams outlier = make_default_outlier();  ///< R = 0.25 m, k = 4 (on centroids)
  /// Threads for every stage (overrides the stages' own num_threads): 0 = all, < 0 invalid.
  int num_threads = 1;
  /// Throws ds3d::InvalidArgument naming the bad field and value.
  void validate() const;

  /// Defaults of `ground`: t = 0.02 m, 2000 iterations (triples off the prior are rejected
  /// before scoring, so most cost almost nothing), prior -y within 30°, camera above it.
  static RansacPlaneParams make_default_ground() {
    RansacPlaneParams p;
    p.distance_threshold = 0.02;
    p.max_iterations = 2000;
    p.normal_prior = Eigen::Vector3d(0.0, -1.0, 0.0);
    p.max_angle_deg = 30.0;
    p.origin_above = true;
    return p;
  }
  /// Defaults of `depth`: stride 2, everything else as DepthToPointsParams.
  static DepthToPointsParams make_default_depth() {
    DepthToPointsParams p;
    p.stride = 2;
    return p;
  }
  /// Defaults of `voxel`: leaf 0.1 m.
  static VoxelGridParams make_default_voxel() {
    VoxelGridParams p;
    p.leaf_size = 0.1;
    return p;
  }
  /// Defaults of `outlier`: R = 0.25 m, k = 4 (sized for 0.1 m centroids: a centroid needs a
  /// few neighbours within 2.5 leaves).
  static RadiusOutlierParams make_default_outlier() {
    RadiusOutlierParams p;
    p.radius = 0.25;
    p.min_neighbors = 4;
    return p;
  }
};

/// Output of preprocess().
struct PreprocessResult {
  Points3f points;                    ///< detector input: kept voxel centroids [m], key order
  std::vector<std::uint32_t> voxel;   ///< for each output row, its row in the voxel stage
  std::vector<std::uint32_t> source;  ///< for each output row, the representative input point
  Pixels2i pixels;                    ///< (u, v) of each source point (depth input only)
  bool ground_found = false;          ///< a ground plane was found and removed
  Eigen::Vector4d ground_plane = Eigen::Vector4d::Zero();  ///< (a, b, c, d) when ground_found
  std::size_t num_input = 0;       ///< points after back-projection (or given)
  std::size_t num_voxels = 0;      ///< centroids after down-sampling
  std::size_t num_ground = 0;      ///< centroids removed as ground
  std::size_t num_outliers = 0;    ///< centroids removed as outliers
  std::size_t num_non_finite = 0;  ///< input points skipped as non-finite
  /// @{
  /// Wall time per stage [ms]: depth, voxel, ground, outlier (depth is 0 for cloud input).
  double ms_depth = 0, ms_voxel = 0, ms_ground = 0, ms_outlier = 0;
  /// @}
};

/// Runs the whole chain on a 16-bit depth image (see depth_to_points for the image arguments).
/// @throws ds3d::InvalidArgument on bad params, image or camera.
/// @note Deterministic; identical output for any num_threads. About O(pixels) time.
[[nodiscard]] PreprocessResult preprocess(const std::uint16_t* depth, int width, int height,
                                          std::ptrdiff_t row_stride, const PinholeCamera& camera,
                                          const PreprocessParams& params = {});

/// Runs the whole chain on a 16-bit depth image given as an Eigen row-major matrix.
[[nodiscard]] PreprocessResult preprocess(
    const Eigen::Ref<const DepthImageU16, 0, Eigen::OuterStride<>>& depth,
    const PinholeCamera& camera, const PreprocessParams& params = {});

/// Runs voxel → ground → outlier on an existing cloud (params.depth is not used; `pixels` is
/// empty and `source` indexes `cloud`).
/// @throws ds3d::InvalidArgument on bad params or a non-finite point under kThrow.
template <PointCloud C>
[[nodiscard]] PreprocessResult preprocess_cloud(const C& cloud,
                                                const PreprocessParams& params = {});

}  // namespace ds3d

#include "ds3d/detail/preprocess_impl.hpp"
