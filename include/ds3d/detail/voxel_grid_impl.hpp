// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::voxel_grid (included by voxel_grid.hpp). Not API.

#include <limits>

#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/voxel_grid.hpp"

namespace ds3d {

inline void VoxelGridParams::validate() const {
  const char* fn = "ds3d::voxel_grid";
  DS3D_CHECK(std::isfinite(leaf_size.dx) && leaf_size.dx > 0, fn,
             ": leaf_size.dx must be finite and > 0 (got ", leaf_size.dx, ")");
  DS3D_CHECK(std::isfinite(leaf_size.dy) && leaf_size.dy > 0, fn,
             ": leaf_size.dy must be finite and > 0 (got ", leaf_size.dy, ")");
  DS3D_CHECK(std::isfinite(leaf_size.dz) && leaf_size.dz > 0, fn,
             ": leaf_size.dz must be finite and > 0 (got ", leaf_size.dz, ")");
  DS3D_CHECK(min_points >= 1, fn, ": min_points must be >= 1 (got ", min_points, ")");
  (void)detail::resolve_num_threads(num_threads, fn);
}

template <PointCloud C>
VoxelGridResult voxel_grid(const C& cloud, const VoxelGridParams& params) {
  constexpr const char* kFn = "ds3d::voxel_grid";
  params.validate();
  const int threads = detail::resolve_num_threads(params.num_threads, kFn);
  const detail::VoxelSort s =
      detail::sort_by_voxel(cloud, {params.leaf_size.dx, params.leaf_size.dy, params.leaf_size.dz},
                            params.on_non_finite, threads, kFn);

  const std::size_t num_cells = s.num_cells();
  VoxelGridResult r;
  r.num_non_finite = s.num_non_finite;
  // Kept cells first (min_points), so the outputs can be sized once.
  std::vector<std::uint32_t> kept;
  if (params.min_points > 1) {
    kept.reserve(num_cells);
    for (std::size_t c = 0; c < num_cells; ++c) {
      const std::uint32_t cnt = s.cell_begin[c + 1] - s.cell_begin[c];
      if (cnt >= params.min_points) {
        kept.push_back(static_cast<std::uint32_t>(c));
      } else {
        r.num_dropped += cnt;
      }
    }
  }
  const bool all = params.min_points <= 1;
  const std::size_t m = all ? num_cells : kept.size();
  r.centroids.resize(static_cast<Eigen::Index>(m), 3);
  r.keys.resize(static_cast<Eigen::Index>(m), 3);
  r.counts.resize(m);
  r.representative.resize(m);
  // Each voxel is summed in input order (the sort is stable), so the thread count cannot change
  // a single bit of the output.
  detail::parallel_for(m, threads, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t j = b; j < e; ++j) {
      const std::size_t c = all ? j : kept[j];
      const std::uint32_t lo = s.cell_begin[c];
      const std::uint32_t hi = s.cell_begin[c + 1];
      const auto row = static_cast<Eigen::Index>(j);
      r.keys(row, 0) = s.cell_key[c][0];
      r.keys(row, 1) = s.cell_key[c][1];
      r.keys(row, 2) = s.cell_key[c][2];
      r.counts[j] = hi - lo;
      if (hi - lo == 1) {
        r.centroids.row(row) = cloud::point(cloud, s.index[lo]).transpose();
        r.representative[j] = s.index[lo];
        continue;
      }
      double sx = 0;
      double sy = 0;
      double sz = 0;
      for (std::uint32_t k = lo; k < hi; ++k) {
        const Eigen::Vector3f p = cloud::point(cloud, s.index[k]);
        sx += p.x();
        sy += p.y();
        sz += p.z();
      }
      const double inv = 1.0 / static_cast<double>(hi - lo);
      const double mx = sx * inv;
      const double my = sy * inv;
      const double mz = sz * inv;
      std::uint32_t best = s.index[lo];
      double best_d = std::numeric_limits<double>::infinity();
      for (std::uint32_t k = lo; k < hi; ++k) {
        const Eigen::Vector3f p = cloud::point(cloud, s.index[k]);
        const double dx = p.x() - mx;
        const double dy = p.y() - my;
        const double dz = p.z() - mz;
        const double d = dx * dx + dy * dy + dz * dz;
        if (d < best_d) {  // strict: the first (lowest input index) wins ties
          best_d = d;
          best = s.index[k];
        }
      }
      r.centroids(row, 0) = static_cast<float>(mx);
      r.centroids(row, 1) = static_cast<float>(my);
      r.centroids(row, 2) = static_cast<float>(mz);
      r.representative[j] = best;
    }
  });
  return r;
}

}  // namespace ds3d
