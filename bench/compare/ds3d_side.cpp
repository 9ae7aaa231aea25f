// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d_side.hpp"

#include <cmath>

#include "ds3d/preprocess/radius_outlier.hpp"
#include "ds3d/preprocess/ransac_plane.hpp"
#include "ds3d/preprocess/rgbd.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"
#include "support/depth_scene.hpp"

namespace ds3d_side {
namespace {

Eigen::Map<const ds3d::Points3f> view(const std::vector<float>& xyz) {
  return {xyz.data(), static_cast<Eigen::Index>(xyz.size() / 3), 3};
}

}  // namespace

std::vector<float> room_cloud(std::int64_t size) {
  ds3d::PinholeCamera cam;
  if (size > 400'000) {
    cam.width = 1280;
    cam.height = 800;
    cam.fx = cam.fy = 1050.0;
    cam.cx = 639.5;
    cam.cy = 399.5;
  }
  const auto frame = ds3d::test::render_room(1, cam);
  const ds3d::Points3f p =
      ds3d::depth_to_points(frame.depth.data(), frame.camera.width, frame.camera.height,
                            frame.camera.width, frame.camera)
          .points;
  return {p.data(), p.data() + p.size()};
}

double voxel_count(const std::vector<float>& xyz, double leaf) {
  const Eigen::Ref<const ds3d::Points3f> p = view(xyz);
  return static_cast<double>(ds3d::voxel_grid(p, {.leaf_size = leaf}).counts.size());
}

double voxel_count_workspace(const std::vector<float>& xyz, double leaf) {
  static ds3d::VoxelGridWorkspace ws;  // this benchmark program only
  const Eigen::Ref<const ds3d::Points3f> p = view(xyz);
  return static_cast<double>(ds3d::voxel_grid(p, {.leaf_size = leaf}, ws).counts.size());
}

double radius_kept(const std::vector<float>& xyz, bool kdtree) {
  const Eigen::Ref<const ds3d::Points3f> p = view(xyz);
  return static_cast<double>(
      ds3d::remove_radius_outliers(
          p, {.radius = 0.05,
              .min_neighbors = 16,
              .search = kdtree ? ds3d::RadiusSearch::kKdTree : ds3d::RadiusSearch::kGrid})
          .kept.size());
}

std::array<double, 4> ransac(const std::vector<float>& xyz) {
  const Eigen::Ref<const ds3d::Points3f> p = view(xyz);
  ds3d::RansacPlaneParams params;
  params.distance_threshold = 0.01;
  params.max_iterations = 1000;
  params.confidence = 1.0;
  const Eigen::Vector4d pl = ds3d::ransac_plane(p, params).plane;
  return {pl[0], pl[1], pl[2], pl[3]};
}

double plane_inliers(const std::vector<float>& xyz, std::array<double, 4> plane, double t) {
  const double norm = std::sqrt(plane[0] * plane[0] + plane[1] * plane[1] + plane[2] * plane[2]);
  if (!(norm > 0)) return 0;
  for (double& c : plane) c /= norm;
  std::size_t n = 0;
  for (std::size_t i = 0; i + 2 < xyz.size(); i += 3) {
    const double d = plane[0] * xyz[i] + plane[1] * xyz[i + 1] + plane[2] * xyz[i + 2] + plane[3];
    n += std::abs(d) < t ? 1 : 0;
  }
  return static_cast<double>(n);
}

}  // namespace ds3d_side
