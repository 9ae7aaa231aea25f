// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::preprocess (included by preprocess.hpp). Not API.

#include <chrono>

#include "ds3d/detail/parallel.hpp"
#include "ds3d/preprocess/preprocess.hpp"

namespace ds3d {

inline void PreprocessParams::validate() const {
  const char* fn = "ds3d::preprocess";
  (void)detail::resolve_num_threads(num_threads, fn);
  DS3D_CHECK(min_ground_fraction >= 0.0 && min_ground_fraction <= 1.0, fn,
             ": min_ground_fraction must be in [0, 1] (got ", min_ground_fraction, ")");
  depth.validate();
  voxel.validate();
  if (remove_ground) ground.validate();
  if (remove_outliers) outlier.validate();
}

namespace detail {

inline double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// Voxel → ground → outlier on `cloud`; fills everything but pixels and ms_depth.
template <PointCloud C>
PreprocessResult preprocess_stages(const C& cloud, const PreprocessParams& params) {
  using Clock = std::chrono::steady_clock;
  PreprocessResult r;
  r.num_input = cloud::size(cloud);

  auto t0 = Clock::now();
  VoxelGridParams vp = params.voxel;
  vp.num_threads = params.num_threads;
  const VoxelGridResult vox = voxel_grid(cloud, vp);
  r.ms_voxel = ms_since(t0);
  r.num_voxels = static_cast<std::size_t>(vox.centroids.rows());
  r.num_non_finite = vox.num_non_finite;

  // Rows of `vox` still alive, ascending.
  std::vector<std::uint32_t> alive(r.num_voxels);
  for (std::size_t i = 0; i < alive.size(); ++i) alive[i] = static_cast<std::uint32_t>(i);

  t0 = Clock::now();
  if (params.remove_ground && r.num_voxels >= 3) {
    RansacPlaneParams gp = params.ground;
    gp.num_threads = params.num_threads;
    const RansacPlaneResult plane = ransac_plane(vox.centroids, gp);
    const double need = params.min_ground_fraction * static_cast<double>(r.num_voxels);
    if (plane.found && static_cast<double>(plane.inliers.size()) >= need) {
      r.ground_found = true;
      r.ground_plane = plane.plane;
      r.num_ground = plane.inliers.size();
      std::vector<std::uint32_t> rest;
      rest.reserve(alive.size() - plane.inliers.size());
      std::size_t k = 0;
      for (const std::uint32_t i : alive) {
        if (k < plane.inliers.size() && plane.inliers[k] == i) {
          ++k;
        } else {
          rest.push_back(i);
        }
      }
      alive.swap(rest);
    }
  }
  r.ms_ground = ms_since(t0);

  t0 = Clock::now();
  if (params.remove_outliers && !alive.empty()) {
    Points3f sub(static_cast<Eigen::Index>(alive.size()), 3);
    for (std::size_t i = 0; i < alive.size(); ++i) {
      sub.row(static_cast<Eigen::Index>(i)) = vox.centroids.row(alive[i]);
    }
    RadiusOutlierParams op = params.outlier;
    op.num_threads = params.num_threads;
    const RadiusOutlierResult ro = remove_radius_outliers(sub, op);
    r.num_outliers = alive.size() - ro.kept.size();
    std::vector<std::uint32_t> rest;
    rest.reserve(ro.kept.size());
    for (const std::uint32_t k : ro.kept) rest.push_back(alive[k]);
    alive.swap(rest);
  }
  r.ms_outlier = ms_since(t0);

  r.points.resize(static_cast<Eigen::Index>(alive.size()), 3);
  r.voxel = alive;
  r.source.resize(alive.size());
  for (std::size_t i = 0; i < alive.size(); ++i) {
    r.points.row(static_cast<Eigen::Index>(i)) = vox.centroids.row(alive[i]);
    r.source[i] = vox.representative[alive[i]];
  }
  return r;
}

}  // namespace detail

template <PointCloud C>
PreprocessResult preprocess_cloud(const C& cloud, const PreprocessParams& params) {
  params.validate();
  return detail::preprocess_stages(cloud, params);
}

inline PreprocessResult preprocess(const std::uint16_t* depth, int width, int height,
                                   std::ptrdiff_t row_stride, const PinholeCamera& camera,
                                   const PreprocessParams& params) {
  params.validate();
  const auto t0 = std::chrono::steady_clock::now();
  const DepthToPointsResult pts =
      depth_to_points(depth, width, height, row_stride, camera, params.depth);
  const double ms_depth = detail::ms_since(t0);
  PreprocessResult r = detail::preprocess_stages(pts.points, params);
  r.ms_depth = ms_depth;
  r.pixels.resize(static_cast<Eigen::Index>(r.source.size()), 2);
  for (std::size_t i = 0; i < r.source.size(); ++i) {
    r.pixels.row(static_cast<Eigen::Index>(i)) = pts.pixels.row(r.source[i]);
  }
  return r;
}

inline PreprocessResult preprocess(
    const Eigen::Ref<const DepthImageU16, 0, Eigen::OuterStride<>>& depth,
    const PinholeCamera& camera, const PreprocessParams& params) {
  DS3D_CHECK(depth.rows() <= std::numeric_limits<int>::max() &&
                 depth.cols() <= std::numeric_limits<int>::max(),
             "ds3d::preprocess: image too large");
  return preprocess(depth.data(), static_cast<int>(depth.cols()), static_cast<int>(depth.rows()),
                    depth.outerStride(), camera, params);
}

}  // namespace ds3d
