// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::voxel_grid (included by voxel_grid.hpp). Not API.

#include <bit>
#include <cstring>
#include <limits>
#include <type_traits>

#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_grid_dense.hpp"
#include "ds3d/detail/voxel_grid_rows.hpp"
#include "ds3d/detail/voxel_grid_sort_pairs.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"

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

namespace detail {

/// Bytes held by the buffers of a workspace.
[[nodiscard]] inline std::size_t workspace_bytes(const VoxelGridWorkspace& ws) noexcept {
  return 2 * ws.capacity * sizeof(std::uint64_t) + ws.cell_capacity * sizeof(std::uint32_t) +
         ws.hist.capacity() * sizeof(std::uint32_t) + ws.runs.capacity() * sizeof(std::size_t) +
         ws.occupied.capacity() * sizeof(std::uint64_t) +
         ws.rank.capacity() * sizeof(std::uint32_t) + ws.acc.capacity() * sizeof(double) +
         ws.best.capacity() * sizeof(std::uint64_t);
}

/// The calling thread's workspace of the plain voxel_grid() overload (one per thread, shared by
/// every point type).
[[nodiscard]] inline VoxelGridWorkspace& thread_voxel_workspace() {
  thread_local VoxelGridWorkspace ws;
  return ws;
}

}  // namespace detail

inline std::size_t release_voxel_grid_scratch() noexcept {
  VoxelGridWorkspace& ws = detail::thread_voxel_workspace();
  const std::size_t bytes = detail::workspace_bytes(ws);
  ws = VoxelGridWorkspace{};
  return bytes;
}

template <PointCloud C>
VoxelGridResult voxel_grid(const C& cloud, const VoxelGridParams& params) {
  VoxelGridWorkspace& ws = detail::thread_voxel_workspace();
  // Keep the buffers for the thread's next call unless they outgrew the cap (also when the call
  // throws): fresh scratch costs page faults of the order of the call itself.
  struct Trim {
    VoxelGridWorkspace& ws;
    ~Trim() {
      if (detail::workspace_bytes(ws) > kVoxelGridCachedScratchBytes) {
        (void)release_voxel_grid_scratch();
      }
    }
  } trim{ws};
  return voxel_grid(cloud, params, ws);
}

template <PointCloud C>
VoxelGridResult voxel_grid(const C& cloud, const VoxelGridParams& params, VoxelGridWorkspace& ws) {
  constexpr const char* kFn = "ds3d::voxel_grid";
  params.validate();
  const std::size_t n = cloud::size(cloud);
  const int resolved = detail::resolve_num_threads(params.num_threads, kFn);
  const int threads = n < params.parallel_min_points ? 1 : resolved;
  DS3D_CHECK(n < std::numeric_limits<std::uint32_t>::max(), kFn,
             ": clouds are limited to 2^32 - 1 points (got ", n, ")");
  VoxelGridResult r;
  if (n == 0) return r;
  const std::array<double, 3> leaf{params.leaf_size.dx, params.leaf_size.dy, params.leaf_size.dz};
  // Pass 1 (parallel, streaming): the exact key box of the finite points.
  const detail::VoxelBox box = detail::voxel_box(cloud, leaf, params.on_non_finite, threads, kFn);
  r.num_non_finite = box.non_finite;
  if (box.non_finite == n) return r;
  constexpr std::int64_t kLim = std::int64_t{1} << 21;  // grid_keys_block's error bound
  bool fits = true;
  std::array<std::uint64_t, 3> range{};  // cells per axis
  std::array<int, 3> b{};                // bits per field
  for (std::size_t d = 0; d < 3; ++d) {
    fits = fits && box.lo[d] > -kLim && box.hi[d] < kLim;
    range[d] = static_cast<std::uint64_t>(box.hi[d] - box.lo[d]) + 1;
    b[d] = detail::bits_for(range[d] - 1);
  }
  if (fits) {
    detail::KeyGrid g;
    g.leaf = leaf;
    g.inv = {1.0 / leaf[0], 1.0 / leaf[1], 1.0 / leaf[2]};
    g.lo = box.lo;
    // Dense box (typical for depth frames at a few cm): no sort at all, an occupancy bitmap gives
    // each voxel its row. A box of up to 16 cells per point costs at most 2 bytes per point.
    const std::uint64_t cells = range[0] * range[1] * range[2];  // < 2^66 / 2^3: see fits
    if (b[0] + b[1] + b[2] <= 40 &&
        cells <= std::max<std::uint64_t>(16 * std::uint64_t{n}, 1U << 16) &&
        cells < detail::kNoKey) {
      g.mul = {static_cast<std::uint32_t>(range[1] * range[2]),
               static_cast<std::uint32_t>(range[2]), 1U};
      detail::voxel_grid_dense(cloud, params, threads, g, range, cells, ws, r);
      return r;
    }
    const int bits = b[0] + b[1] + b[2] + (box.non_finite > 0 ? 1 : 0);  // + 1: kNoKey last
    if (bits <= 32) {
      g.mul = {1U << static_cast<unsigned>(b[1] + b[2]), 1U << static_cast<unsigned>(b[2]), 1U};
      detail::voxel_grid_sorted(cloud, params, threads, g, b, bits, ws, r);
      return r;
    }
  }
  // Rare: keys beyond ±2^21 or a sparse box of more than 2^32 cells (int64 triples or 64-bit
  // keys, keys recomputed).
  return detail::voxel_grid_from_sort(
      cloud, params, threads,
      detail::sort_by_voxel(cloud, leaf, params.on_non_finite, threads, kFn));
}

}  // namespace ds3d
