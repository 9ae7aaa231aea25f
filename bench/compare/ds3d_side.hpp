// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// The ds3d half of compare_open3d_pcl, compiled in its own translation unit with the project's
// SIMD flags (DS3D_SIMD, AVX2+FMA on this machine) while Open3D and PCL are used from a baseline
// (SSE2) unit. Only plain arrays cross the boundary: Eigen 3.4 allocates heap matrices
// differently under AVX and SSE, so no Eigen heap object may be shared between the two units.
#include <array>
#include <cstdint>
#include <vector>

namespace ds3d_side {

/// The rendered room frame (tests/support/depth_scene.hpp) back-projected: ~300k points at
/// 640x480 for sizes <= 400k, ~1M at 1280x800 otherwise; xyz interleaved [m].
std::vector<float> room_cloud(std::int64_t size);

/// Number of voxels of ds3d::voxel_grid at a cubic leaf [m] (a fresh call, as Open3D and PCL).
double voxel_count(const std::vector<float>& xyz, double leaf);
/// The same with one VoxelGridWorkspace kept across calls (the per-frame use).
double voxel_count_workspace(const std::vector<float>& xyz, double leaf);
/// Kept points of ds3d::remove_radius_outliers (R 0.05 m, k 16), grid or KD-tree search.
double radius_kept(const std::vector<float>& xyz, bool kdtree);
/// Plane of ds3d::ransac_plane (t 0.01 m, 1000 hypotheses, confidence 1).
std::array<double, 4> ransac(const std::vector<float>& xyz);
/// Points with |n·p + d| < t for the plane normalised to a unit normal, counted in double.
double plane_inliers(const std::vector<float>& xyz, std::array<double, 4> plane, double t);

}  // namespace ds3d_side
