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
  const detail::FinitePoints f = detail::gather_finite(cloud, params.on_non_finite, kFn);
  const detail::SortedKeys s = detail::sort_by_voxel(
      f, {params.leaf_size.dx, params.leaf_size.dy, params.leaf_size.dz}, threads, kFn);

  const std::size_t num_cells = s.cell_begin.size() - 1;
  // Kept cells first (min_points), so the outputs can be sized once.
  std::vector<std::uint32_t> kept;
  kept.reserve(num_cells);
  VoxelGridResult r;
  r.num_non_finite = f.num_non_finite;
  for (std::size_t c = 0; c < num_cells; ++c) {
    const std::uint32_t cnt = s.cell_begin[c + 1] - s.cell_begin[c];
    if (cnt >= params.min_points) {
      kept.push_back(static_cast<std::uint32_t>(c));
    } else {
      r.num_dropped += cnt;
    }
  }
  const auto m = static_cast<Eigen::Index>(kept.size());
  r.centroids.resize(m, 3);
  r.keys.resize(m, 3);
  r.counts.resize(kept.size());
  r.representative.resize(kept.size());
  // Each voxel is summed in input order (the sort is stable), so the thread count cannot change
  // a single bit of the output.
  detail::parallel_for(kept.size(), threads, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t j = b; j < e; ++j) {
      const std::uint32_t c = kept[j];
      const std::uint32_t lo = s.cell_begin[c];
      const std::uint32_t hi = s.cell_begin[c + 1];
      double sx = 0;
      double sy = 0;
      double sz = 0;
      for (std::uint32_t k = lo; k < hi; ++k) {
        const std::uint32_t p = s.order[k];
        sx += f.x[p];
        sy += f.y[p];
        sz += f.z[p];
      }
      const double inv = 1.0 / static_cast<double>(hi - lo);
      const double mx = sx * inv;
      const double my = sy * inv;
      const double mz = sz * inv;
      std::uint32_t best = s.order[lo];
      if (hi - lo > 1) {
        double best_d = std::numeric_limits<double>::infinity();
        for (std::uint32_t k = lo; k < hi; ++k) {
          const std::uint32_t p = s.order[k];
          const double dx = f.x[p] - mx;
          const double dy = f.y[p] - my;
          const double dz = f.z[p] - mz;
          const double d = dx * dx + dy * dy + dz * dz;
          if (d < best_d) {  // strict: the first (lowest input index) wins ties
            best_d = d;
            best = p;
          }
        }
      }
      const auto row = static_cast<Eigen::Index>(j);
      r.centroids(row, 0) = static_cast<float>(mx);
      r.centroids(row, 1) = static_cast<float>(my);
      r.centroids(row, 2) = static_cast<float>(mz);
      const std::uint32_t first = s.order[lo];
      r.keys(row, 0) = s.ix[first];
      r.keys(row, 1) = s.iy[first];
      r.keys(row, 2) = s.iz[first];
      r.counts[j] = hi - lo;
      r.representative[j] = f.index[best];
    }
  });
  return r;
}

}  // namespace ds3d
