// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::voxel_grid (included by voxel_grid.hpp). Not API.

#include <cstring>
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

namespace detail {

/// Centroids from a general VoxelSort (fallback for keys beyond ±2^20 or > 32 key bits).
template <PointCloud C>
VoxelGridResult voxel_grid_from_sort(const C& cloud, const VoxelGridParams& params, int threads,
                                     const VoxelSort& s) {
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

/// Stable LSD radix sort of a[0, m) by `passes` digits of `digit` bits from bit `base` up, using
/// `tmp` (m words) and the histograms already counted in `hist` (passes × 2^digit); returns the
/// buffer holding the result.
inline std::uint64_t* radix_sort_pairs(std::uint64_t* a, std::uint64_t* tmp, std::size_t m,
                                       std::uint32_t* hist, int passes, int digit, int base) {
  const std::size_t buckets = std::size_t{1} << digit;
  const std::uint64_t mask = buckets - 1;
  for (int p = 0; p < passes; ++p) {
    std::uint32_t* c = hist + static_cast<std::size_t>(p) * buckets;
    std::uint32_t sum = 0;
    for (std::size_t b = 0; b < buckets; ++b) {
      const std::uint32_t t = c[b];
      c[b] = sum;
      sum += t;
    }
    const int shift = base + p * digit;
    for (std::size_t k = 0; k < m; ++k) {
      const std::uint64_t w = a[k];
      tmp[c[(w >> shift) & mask]++] = w;
    }
    std::swap(a, tmp);
  }
  return a;
}

}  // namespace detail

template <PointCloud C>
VoxelGridResult voxel_grid(const C& cloud, const VoxelGridParams& params) {
  VoxelGridWorkspace ws;
  return voxel_grid(cloud, params, ws);
}

template <PointCloud C>
VoxelGridResult voxel_grid(const C& cloud, const VoxelGridParams& params, VoxelGridWorkspace& ws) {
  constexpr const char* kFn = "ds3d::voxel_grid";
  params.validate();
  const int threads = detail::resolve_num_threads(params.num_threads, kFn);
  const std::size_t n = cloud::size(cloud);
  DS3D_CHECK(n < std::numeric_limits<std::uint32_t>::max(), kFn,
             ": clouds are limited to 2^32 - 1 points (got ", n, ")");
  VoxelGridResult r;
  if (n == 0) return r;
  const std::array<double, 3> leaf{params.leaf_size.dx, params.leaf_size.dy, params.leaf_size.dz};
  if (ws.capacity < n) {  // default-initialised: no zero-fill of buffers written before read
    ws.words = std::make_unique_for_overwrite<std::uint64_t[]>(n);
    ws.tmp = std::make_unique_for_overwrite<std::uint64_t[]>(n);
    ws.capacity = n;
  }
  // Pass 1 (parallel, SSE2): exact packed key of every point, per-axis key bounds.
  const detail::PackedKeyInfo info =
      detail::packed_voxel_keys(cloud, leaf, params.on_non_finite, threads, kFn, ws.words.get());
  r.num_non_finite = info.non_finite;
  const std::size_t m = n - info.non_finite;
  if (m == 0) return r;
  int bits = 64;
  std::array<int, 3> b{};
  if (!info.wide) {
    for (std::size_t d = 0; d < 3; ++d) {
      b[d] = detail::bits_for(static_cast<std::uint64_t>(info.hi[d] - info.lo[d]));
    }
    bits = b[0] + b[1] + b[2];
  }
  if (bits > 32) {  // rare: general path (int64 triples or 64-bit keys, keys recomputed)
    return detail::voxel_grid_from_sort(
        cloud, params, threads,
        detail::sort_by_voxel(cloud, leaf, params.on_non_finite, threads, kFn));
  }

  // Pass 2 (serial, streaming): compact each key to its used bits (fields relative to their
  // minima, lexicographic order kept), pair it with the index, count all radix histograms.
  constexpr std::int64_t kHalf = detail::PackedKeyInfo::kHalf;
  const std::uint64_t ox = static_cast<std::uint64_t>(info.lo[0] + kHalf);
  const std::uint64_t oy = static_cast<std::uint64_t>(info.lo[1] + kHalf);
  const std::uint64_t oz = static_cast<std::uint64_t>(info.lo[2] + kHalf);
  const auto sy = static_cast<unsigned>(b[2]);
  const auto sx = static_cast<unsigned>(b[1] + b[2]);
  const int passes = (bits + 10) / 11;
  const int digit = passes == 0 ? 0 : (bits + passes - 1) / passes;
  const std::size_t buckets = std::size_t{1} << digit;
  const std::uint64_t dmask = buckets - 1;
  // Always three histograms: a pass beyond `passes` sees only zero bits (bucket 0), so the
  // counting loop has no inner loop.
  ws.hist.assign(buckets * 3, 0U);
  std::uint64_t* a = ws.words.get();
  std::uint32_t* hist = ws.hist.data();
  {
    std::size_t k = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint64_t w = a[i];
      if (w == detail::kNonFiniteKey) continue;
      const std::uint64_t fx = (w >> 42U) - ox;
      const std::uint64_t fy = ((w >> 21U) & 0x1FFFFFU) - oy;
      const std::uint64_t fz = (w & 0x1FFFFFU) - oz;
      const std::uint64_t key = (fx << sx) | (fy << sy) | fz;
      a[k++] = (key << 32U) | i;  // k <= i: in place
      ++hist[key & dmask];
      ++hist[buckets + ((key >> digit) & dmask)];
      ++hist[2 * buckets + ((key >> (2 * digit)) & dmask)];
    }
  }
  // Pass 3: stable radix sort over the used bits only (0 to 3 passes).
  const std::uint64_t* sorted =
      detail::radix_sort_pairs(a, ws.tmp.get(), m, hist, passes, digit, 32);

  // Pass 4: voxels are runs of equal keys. Chunks start at voxel boundaries; each fills its rows
  // from its first row on (sums in input order: identical for any thread count).
  const std::uint32_t min_pts = params.min_points;
  const auto chunks = static_cast<std::size_t>(std::max(1, threads));
  ws.runs.assign(3 * chunks + 2, 0);
  std::size_t* bound = ws.runs.data();                // chunk c covers [bound[c], bound[c + 1])
  std::size_t* offset = ws.runs.data() + chunks + 1;  // first output row of chunk c
  std::size_t* chunk_dropped = ws.runs.data() + 2 * chunks + 2;  // points dropped by chunk c
  for (std::size_t c = 0; c < chunks; ++c) {
    std::size_t s = detail::chunk_range(m, chunks, c).first;
    while (s > 0 && s < m && (sorted[s] >> 32U) == (sorted[s - 1] >> 32U)) ++s;
    bound[c] = std::max(s, c == 0 ? 0 : bound[c - 1]);
  }
  bound[chunks] = m;
  // Rows and dropped points of chunk c, so that the outputs are allocated once at their exact
  // size (allocating for every point and trimming made glibc return and re-fault the pages: 10x
  // the page faults per call).
  auto count_chunk = [&](std::size_t c) {
    std::size_t kept = 0;
    std::size_t dropped = 0;
    for (std::size_t lo = bound[c], hi = 0; lo < bound[c + 1]; lo = hi) {
      const std::uint64_t key = sorted[lo] >> 32U;
      for (hi = lo + 1; hi < bound[c + 1] && (sorted[hi] >> 32U) == key; ++hi) {
      }
      if (hi - lo >= min_pts) {
        ++kept;
      } else {
        dropped += hi - lo;
      }
    }
    offset[c + 1] = kept;
    return dropped;
  };
  const std::uint64_t zmask = (std::uint64_t{1} << b[2]) - 1;
  const std::uint64_t ymask = (std::uint64_t{1} << b[1]) - 1;
  // Fills the rows of chunk c from offset[c] on.
  auto fill_chunk = [&](std::size_t c) {
    std::size_t row = offset[c];
    std::int64_t* out_key = r.keys.data();
    float* out_c = r.centroids.data();
    std::uint32_t* out_n = r.counts.data();
    std::uint32_t* out_rep = r.representative.data();
    for (std::size_t lo = bound[c], hi = 0; lo < bound[c + 1]; lo = hi) {
      const std::uint64_t key = sorted[lo] >> 32U;
      for (hi = lo + 1; hi < bound[c + 1] && (sorted[hi] >> 32U) == key; ++hi) {
      }
      const std::size_t cnt = hi - lo;
      if (cnt < min_pts) continue;
      out_key[3 * row] = static_cast<std::int64_t>(key >> sx) + info.lo[0];
      out_key[3 * row + 1] = static_cast<std::int64_t>((key >> sy) & ymask) + info.lo[1];
      out_key[3 * row + 2] = static_cast<std::int64_t>(key & zmask) + info.lo[2];
      out_n[row] = static_cast<std::uint32_t>(cnt);
      const auto first = static_cast<std::uint32_t>(sorted[lo]);
      if (cnt == 1) {
        const Eigen::Vector3f p = cloud::point(cloud, first);
        out_c[3 * row] = p.x();
        out_c[3 * row + 1] = p.y();
        out_c[3 * row + 2] = p.z();
        out_rep[row] = first;
        ++row;
        continue;
      }
      double sum_x = 0;
      double sum_y = 0;
      double sum_z = 0;
      for (std::size_t k = lo; k < hi; ++k) {
        const Eigen::Vector3f p = cloud::point(cloud, static_cast<std::uint32_t>(sorted[k]));
        sum_x += p.x();
        sum_y += p.y();
        sum_z += p.z();
      }
      const double inv_cnt = 1.0 / static_cast<double>(cnt);
      const double mx = sum_x * inv_cnt;
      const double my = sum_y * inv_cnt;
      const double mz = sum_z * inv_cnt;
      std::uint32_t best = first;
      double best_d = std::numeric_limits<double>::infinity();
      for (std::size_t k = lo; k < hi; ++k) {
        const auto i = static_cast<std::uint32_t>(sorted[k]);
        const Eigen::Vector3f p = cloud::point(cloud, i);
        const double dx = p.x() - mx;
        const double dy = p.y() - my;
        const double dz = p.z() - mz;
        const double d = dx * dx + dy * dy + dz * dz;
        best = d < best_d ? i : best;  // strict: the first (lowest input index) wins ties
        best_d = d < best_d ? d : best_d;
      }
      out_c[3 * row] = static_cast<float>(mx);
      out_c[3 * row + 1] = static_cast<float>(my);
      out_c[3 * row + 2] = static_cast<float>(mz);
      out_rep[row] = best;
      ++row;
    }
  };
  detail::parallel_chunks(chunks, chunks, threads,
                          [&](std::size_t cb, std::size_t ce, std::size_t) {
                            for (std::size_t c = cb; c < ce; ++c) chunk_dropped[c] = count_chunk(c);
                          });
  for (std::size_t c = 0; c < chunks; ++c) r.num_dropped += chunk_dropped[c];
  offset[0] = 0;
  for (std::size_t c = 0; c < chunks; ++c) offset[c + 1] += offset[c];
  const std::size_t rows = offset[chunks];
  r.centroids.resize(static_cast<Eigen::Index>(rows), 3);
  r.keys.resize(static_cast<Eigen::Index>(rows), 3);
  r.counts.resize(rows);
  r.representative.resize(rows);
  detail::parallel_chunks(chunks, chunks, threads,
                          [&](std::size_t cb, std::size_t ce, std::size_t) {
                            for (std::size_t c = cb; c < ce; ++c) fill_chunk(c);
                          });
  return r;
}

}  // namespace ds3d
