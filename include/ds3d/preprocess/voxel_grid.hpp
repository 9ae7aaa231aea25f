// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file voxel_grid.hpp
/// @brief Voxel-grid down-sampling to per-voxel centroids (3DS-SLAM §III-B input compression).
///
/// A point's voxel is `(floor(x/dx), floor(y/dy), floor(z/dz))`: the grid is anchored at the
/// origin (not at the cloud's bounding box, unlike Open3D's VoxelDownSample), the division is
/// done in double and the key is a signed 64-bit integer per axis. Each occupied voxel yields the
/// mean of its member points, accumulated in double. Output rows are sorted by key (ix, iy, iz),
/// so the result is identical for every thread count.

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "ds3d/cloud.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// Voxel edge lengths [m]. Converts implicitly from one double (cubic voxels) or three.
struct LeafSize {
  double dx = 0.05;  ///< edge along x [m], finite and > 0
  double dy = 0.05;  ///< edge along y [m], finite and > 0
  double dz = 0.05;  ///< edge along z [m], finite and > 0
  LeafSize() = default;
  /// Cubic voxels of edge `s` [m].
  LeafSize(double s)
      : dx(s), dy(s), dz(s) {}  // NOLINT(google-explicit-constructor): `.leaf_size = 0.02`
  /// Anisotropic voxels [m].
  LeafSize(double x, double y, double z) : dx(x), dy(y), dz(z) {}
};

/// Parameters of voxel_grid().
struct VoxelGridParams {
  LeafSize leaf_size{0.05};                    ///< voxel edges [m], each finite and > 0
  std::uint32_t min_points = 1;                ///< voxels with fewer members are dropped, >= 1
  NonFinite on_non_finite = NonFinite::kSkip;  ///< kSkip: ignore and count; kThrow: InvalidArgument
  int num_threads = 1;                         ///< 0 = all hardware threads, < 0 is invalid
  /// Clouds of fewer points run on one thread whatever num_threads says: each parallel pass
  /// starts its threads anew, which costs more than it saves on small clouds (2-vCPU AMD EPYC,
  /// BM_VoxelGridSmall, 5 cm leaf: 10,000 points 0.10 ms on one thread against 0.30 ms on two,
  /// 100,000 points 1.07 against 1.20 ms; BM_VoxelGrid, the 300,000-point frame at 1 cm: 3.36
  /// against 2.54 ms; docs/benchmarks.md). 0 = always num_threads.
  std::size_t parallel_min_points = 200000;
  /// Throws ds3d::InvalidArgument naming the bad field and value.
  void validate() const;
};

/// Output of voxel_grid(): one row per kept voxel, sorted by key (ix, iy, iz).
struct VoxelGridResult {
  /// Integer voxel keys, row-major M×3 (numpy (M, 3) int64).
  using Keys = Eigen::Matrix<std::int64_t, Eigen::Dynamic, 3, Eigen::RowMajor>;
  Points3f centroids;                 ///< mean of each voxel's members [m] (double sums)
  Keys keys;                          ///< (ix, iy, iz) of each voxel
  std::vector<std::uint32_t> counts;  ///< number of member points of each voxel
  std::vector<std::uint32_t>
      representative;              ///< member nearest its centroid (input index; ties: lowest)
  std::size_t num_non_finite = 0;  ///< input points skipped as non-finite
  std::size_t num_dropped = 0;     ///< finite points in voxels below min_points
};

/// Scratch buffers of voxel_grid(). Pass the same workspace to repeated calls (one per thread)
/// and the fast path allocates nothing but the outputs. Contents are unspecified between calls.
struct VoxelGridWorkspace {
  detail::Scratch<std::uint64_t> words;  ///< sparse box: 32-bit keys, then radix-sort pairs
  detail::Scratch<std::uint64_t> tmp;    ///< radix-sort ping-pong buffer (not zero-filled)
  std::size_t capacity = 0;              ///< words of each of words / tmp
  std::vector<std::uint32_t> hist;       ///< radix histograms
  std::vector<std::size_t> runs;         ///< per-chunk counts (bounds, offsets, dropped points)
  detail::Scratch<std::uint32_t> cell;   ///< dense box: key, then output row, of each point
  std::size_t cell_capacity = 0;         ///< entries of cell
  std::vector<std::uint64_t> occupied;   ///< dense box: occupancy bitmap of the key box
  std::vector<std::uint32_t> rank;       ///< dense box: set bits before each bitmap word
  std::vector<double> acc;               ///< dense box: per-voxel sums, then means
  std::vector<std::uint64_t> best;       ///< dense box: bits of each voxel's best distance
};

/// Scratch the plain voxel_grid() overload keeps per thread between calls [bytes]: its buffers
/// stay allocated (about 16–20 bytes per input point on the sorting paths, so up to about 3 M
/// points) unless a call needed more, in which case they are freed when that call returns.
inline constexpr std::size_t kVoxelGridCachedScratchBytes = std::size_t{64} << 20U;

/// Voxel-grid down-sampling: one centroid per occupied voxel of an origin-anchored grid.
/// @param cloud  any PointCloud (see cloud.hpp); non-finite points are ignored and counted.
/// @param params leaf sizes [m], min_points, non-finite policy and threads.
/// @return centroids, keys, counts and representative input indices, sorted by key.
/// @throws ds3d::InvalidArgument on bad params, on a voxel index whose magnitude reaches 2^62
///         (names the coordinate and the value), on a non-finite point under kThrow, on a
///         finite float64 coordinate (Points3d clouds) beyond the float32 range points are read
///         in (|v| > 3.4e38; names the row, axis and value), or on clouds of 2^32 - 1 points or
///         more.
/// @note O(n) time, O(n) extra memory: an occupancy bitmap over the key box when it has at most
///       16 cells per point or 2^16 cells (no sort), else a radix sort on packed keys (a comparison
///       sort when the occupied key ranges need more than 64 bits). Identical output for every
///       num_threads and every path (each voxel is summed in input order).
/// @note Scratch: a thread-local VoxelGridWorkspace, kept between calls on the same thread up
///       to kVoxelGridCachedScratchBytes (fresh scratch costs as much in page faults as the
///       call itself at 0.01 m). Pass your own workspace to the overload below to control it.
template <PointCloud C>
[[nodiscard]] VoxelGridResult voxel_grid(const C& cloud, const VoxelGridParams& params = {});

/// As above, with caller-owned scratch buffers (no per-call allocation beyond the outputs once
/// the buffers have grown, on the fast paths: every key within ±2^21 and either at most 16 box
/// cells per point or a box of at most 2^32 cells).
template <PointCloud C>
[[nodiscard]] VoxelGridResult voxel_grid(const C& cloud, const VoxelGridParams& params,
                                         VoxelGridWorkspace& workspace);

/// Frees the calling thread's cached scratch of the plain voxel_grid() overload (see
/// kVoxelGridCachedScratchBytes), e.g. before a worker thread idles for long. The next plain call
/// on this thread allocates it again. Other threads' scratch is not touched.
/// @return the bytes released (0 when the thread held none).
inline std::size_t release_voxel_grid_scratch() noexcept;

/// Overload for a row-major N×3 float map (numpy float32, no copy).
[[nodiscard]] inline VoxelGridResult voxel_grid(Eigen::Ref<const Points3f> xyz,
                                                const VoxelGridParams& params = {}) {
  return voxel_grid<Eigen::Ref<const Points3f>>(xyz, params);
}

}  // namespace ds3d

#include "ds3d/detail/voxel_grid_impl.hpp"

#if defined(DS3D_CORE_SEPARATE) && !defined(DS3D_CORE_IMPLEMENTATION)
// Compiled once in ds3d_core_separate.cpp (see ds3d/detail/core_separate.hpp).
namespace ds3d {
extern template VoxelGridResult voxel_grid<Points3f>(const Points3f&, const VoxelGridParams&);
extern template VoxelGridResult voxel_grid<Eigen::Ref<const Points3f>>(
    const Eigen::Ref<const Points3f>&, const VoxelGridParams&);
extern template VoxelGridResult voxel_grid<std::vector<Eigen::Vector3f>>(
    const std::vector<Eigen::Vector3f>&, const VoxelGridParams&);
}  // namespace ds3d
#endif
