// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// %s Part of ds3d::voxel_grid (see voxel_grid_impl.hpp). Not API.

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

#if defined(__AVX2__)
#include <immintrin.h>
#endif

#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"

namespace ds3d::detail {

/// Squared distance of a member to its voxel's mean, the representative criterion (one
/// expression shared by every path, so that they agree to the last bit).
[[nodiscard]] inline double member_sq_dist(const Eigen::Vector3f& p, double mx, double my,
                                           double mz) {
  const double dx = p.x() - mx;
  const double dy = p.y() - my;
  const double dz = p.z() - mz;
  return dx * dx + dy * dy + dz * dz;
}

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
        const double d = member_sq_dist(cloud::point(cloud, s.index[k]), mx, my, mz);
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

/// Start of the coordinates of a contiguous row-major cloud (3 floats per point), else nullptr.
template <PointCloud C>
[[nodiscard]] const float* contiguous_xyz(const C& c) {
  if constexpr (std::is_same_v<C, Points3f>) {
    return c.data();
  } else if constexpr (std::is_same_v<C, Eigen::Ref<const Points3f>>) {
    return c.outerStride() == 3 ? c.data() : nullptr;
  } else {
    return nullptr;
  }
}

/// Decodes bit-packed sparse-path keys ((ix - lo_x) << (b_y + b_z) | (iy - lo_y) << b_z |
/// (iz - lo_z), in the high half of a sort pair) into int64 (ix, iy, iz) rows.
struct KeyDecoder {
  unsigned sx;         ///< shift of the x field (b_y + b_z)
  unsigned sy;         ///< shift of the y field (b_z)
  std::uint64_t my;    ///< y field mask
  std::uint64_t mz;    ///< z field mask
  std::int64_t lo[3];  ///< key box minimum

  KeyDecoder(const KeyGrid& g, const std::array<int, 3>& b)
      : sx(static_cast<unsigned>(b[1] + b[2])),
        sy(static_cast<unsigned>(b[2])),
        my((std::uint64_t{1} << b[1]) - 1),
        mz((std::uint64_t{1} << b[2]) - 1),
        lo{g.lo[0], g.lo[1], g.lo[2]} {}

  /// Keys of pairs w[0, len) into out[0, 3 len).
  void decode(const std::uint64_t* w, std::size_t len, std::int64_t* out) const {
    std::size_t j = 0;
#if defined(__AVX2__)
    // Four rows per step: three field vectors, interleaved by lane permutes and blends.
    const __m128i cx = _mm_cvtsi32_si128(static_cast<int>(sx + 32));
    const __m128i cy = _mm_cvtsi32_si128(static_cast<int>(sy + 32));
    const __m256i vmy = _mm256_set1_epi64x(static_cast<long long>(my));
    const __m256i vmz = _mm256_set1_epi64x(static_cast<long long>(mz));
    const __m256i l0 = _mm256_set1_epi64x(lo[0]);
    const __m256i l1 = _mm256_set1_epi64x(lo[1]);
    const __m256i l2 = _mm256_set1_epi64x(lo[2]);
    for (; j + 4 <= len; j += 4) {
      const __m256i k = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(w + j));
      const __m256i x = _mm256_add_epi64(_mm256_srl_epi64(k, cx), l0);
      const __m256i y = _mm256_add_epi64(_mm256_and_si256(_mm256_srl_epi64(k, cy), vmy), l1);
      const __m256i z = _mm256_add_epi64(_mm256_and_si256(_mm256_srli_epi64(k, 32), vmz), l2);
      // [x0 y0 z0 x1] [y1 z1 x2 y2] [z2 x3 y3 z3]
      const __m256i o0 =
          _mm256_blend_epi32(_mm256_blend_epi32(_mm256_permute4x64_epi64(x, 0x40),
                                                _mm256_permute4x64_epi64(y, 0x00), 0x0C),
                             _mm256_permute4x64_epi64(z, 0x00), 0x30);
      const __m256i o1 =
          _mm256_blend_epi32(_mm256_blend_epi32(_mm256_permute4x64_epi64(y, 0x81),
                                                _mm256_permute4x64_epi64(z, 0x04), 0x0C),
                             _mm256_permute4x64_epi64(x, 0x20), 0x30);
      const __m256i o2 =
          _mm256_blend_epi32(_mm256_blend_epi32(_mm256_permute4x64_epi64(z, 0xC2),
                                                _mm256_permute4x64_epi64(x, 0x0C), 0x0C),
                             _mm256_permute4x64_epi64(y, 0x30), 0x30);
      auto* o = reinterpret_cast<__m256i*>(out + 3 * j);
      _mm256_storeu_si256(o, o0);
      _mm256_storeu_si256(o + 1, o1);
      _mm256_storeu_si256(o + 2, o2);
    }
#endif
    for (; j < len; ++j) {
      const std::uint64_t k = w[j] >> 32U;
      out[3 * j] = static_cast<std::int64_t>(k >> sx) + lo[0];
      out[3 * j + 1] = static_cast<std::int64_t>((k >> sy) & my) + lo[1];
      out[3 * j + 2] = static_cast<std::int64_t>(k & mz) + lo[2];
    }
  }
};

/// Output rows of the sparse path for min_points == 1 from the sorted (key << 32 | index) pairs
/// sorted[0, bound[chunks]), chunk c from row offset[c] on. Pairs are taken in blocks: (a) the
/// end of every run of equal keys in the block, one branch-free step per pair, into an L1
/// buffer; (b) counts, first members and keys of those rows; (c) centroids of every row as if it
/// had one member (a straight copy of the point: the bits of a one-member sum), listing the rows
/// with more members; (d) those rows summed in input order and their representative chosen.
/// Same output as the per-run loop, with no branch on the (unpredictable) run length.
template <PointCloud C>
void sparse_rows(const C& cloud, std::size_t c, const KeyGrid& g, const std::array<int, 3>& b,
                 const std::uint64_t* sorted, const std::size_t* bound, std::size_t row0,
                 bool append, VoxelGridResult& r) {
  const float* const xyz = contiguous_xyz(cloud);
  auto point = [&](std::uint32_t i) {
    if (xyz != nullptr) {
      const float* q = xyz + 3 * std::size_t{i};
      return Eigen::Vector3f(q[0], q[1], q[2]);
    }
    return Eigen::Vector3f(cloud::point(cloud, i));
  };
  const KeyDecoder dec(g, b);
  std::int64_t* const out_key = r.keys.data();
  float* const out_c = r.centroids.data();
  alignas(64) std::uint32_t out_n[kKeyBlock];    // counts of the block's rows
  alignas(64) std::uint32_t out_rep[kKeyBlock];  // representatives of the block's rows
  alignas(64) std::uint64_t ends[kKeyBlock + 1];
  alignas(64) std::uint64_t w[kKeyBlock];
  alignas(64) std::uint32_t multi[kKeyBlock];
  const std::size_t end = bound[c + 1];
  std::size_t row = row0;
  std::size_t start = bound[c];  // first pair of the current (unfinished) run
  for (std::size_t k0 = bound[c]; k0 < end; k0 += kKeyBlock) {
    const std::size_t k1 = std::min(end, k0 + kKeyBlock);
    // (a) a run ends after pair k when the next key differs (or at the chunk's end).
    std::size_t runs = 0;
    for (std::size_t k = k0; k < k1; ++k) {
      ends[runs] = k + 1;
      const bool last = k + 1 == end || (sorted[k + 1] >> 32U) != (sorted[k] >> 32U);
      runs += last ? 1 : 0;
    }
    // (b) rows of the runs that ended in this block.
    std::size_t num_multi = 0;
    for (std::size_t j = 0; j < runs; ++j) {
      const std::uint64_t pair = sorted[start];
      const auto cnt = static_cast<std::uint32_t>(ends[j] - start);
      w[j] = pair;
      out_n[j] = cnt;
      out_rep[j] = static_cast<std::uint32_t>(pair);
      multi[num_multi] = static_cast<std::uint32_t>(j);
      num_multi += cnt > 1 ? 1 : 0;
      start = ends[j];
    }
    dec.decode(w, runs, out_key + 3 * row);
    // (c) one member: the point itself.
    for (std::size_t j = 0; j < runs; ++j) {
      const Eigen::Vector3f p = point(static_cast<std::uint32_t>(w[j]));
      out_c[3 * (row + j)] = p.x();
      out_c[3 * (row + j) + 1] = p.y();
      out_c[3 * (row + j) + 2] = p.z();
    }
    // (d) more members: mean in input order, then the first member nearest it.
    for (std::size_t q = 0; q < num_multi; ++q) {
      const std::size_t j = multi[q];
      const std::size_t hi = ends[j];
      const std::size_t lo = hi - out_n[j];
      double sum_x = 0;
      double sum_y = 0;
      double sum_z = 0;
      for (std::size_t k = lo; k < hi; ++k) {
        const Eigen::Vector3f p = point(static_cast<std::uint32_t>(sorted[k]));
        sum_x += p.x();
        sum_y += p.y();
        sum_z += p.z();
      }
      const double inv_cnt = 1.0 / static_cast<double>(hi - lo);
      const double mx = sum_x * inv_cnt;
      const double my = sum_y * inv_cnt;
      const double mz = sum_z * inv_cnt;
      auto best = static_cast<std::uint32_t>(sorted[lo]);
      double best_d = std::numeric_limits<double>::infinity();
      for (std::size_t k = lo; k < hi; ++k) {
        const auto i = static_cast<std::uint32_t>(sorted[k]);
        const double d = member_sq_dist(point(i), mx, my, mz);
        best = d < best_d ? i : best;  // strict: the first (lowest input index) wins ties
        best_d = d < best_d ? d : best_d;
      }
      out_c[3 * (row + j)] = static_cast<float>(mx);
      out_c[3 * (row + j) + 1] = static_cast<float>(my);
      out_c[3 * (row + j) + 2] = static_cast<float>(mz);
      out_rep[j] = best;
    }
    // Counts and representatives leave L1 once: appended to reserved vectors (one chunk: no
    // zero-fill of the outputs) or copied to the chunk's rows.
    if (append) {
      r.counts.insert(r.counts.end(), out_n, out_n + runs);
      r.representative.insert(r.representative.end(), out_rep, out_rep + runs);
    } else {
      std::copy(out_n, out_n + runs, r.counts.data() + row);
      std::copy(out_rep, out_rep + runs, r.representative.data() + row);
    }
    row += runs;
  }
}

/// Rows of chunk c (pairs sorted[bound[c], bound[c + 1])) for min_points > 1, from row offset[c]
/// on: one row per run of at least min_pts equal keys, summed in input order. (Everything read in
/// the loop is a local copy: the int64 / size_t output stores could otherwise alias it.)
template <PointCloud C>
void fill_sorted_rows(const C& cloud, std::size_t c, const KeyGrid& g, const std::array<int, 3>& b,
                      const std::uint64_t* sorted, const std::size_t* bound,
                      const std::size_t* offset, std::uint32_t min_pts, VoxelGridResult& r) {
  const auto sx = static_cast<unsigned>(b[1] + b[2]);
  const auto sy = static_cast<unsigned>(b[2]);
  const std::uint64_t zmask = (std::uint64_t{1} << b[2]) - 1;
  const std::uint64_t ymask = (std::uint64_t{1} << b[1]) - 1;
  std::size_t row = offset[c];
  std::int64_t* const out_key = r.keys.data();
  float* const out_c = r.centroids.data();
  std::uint32_t* const out_n = r.counts.data();
  std::uint32_t* const out_rep = r.representative.data();
  const std::uint64_t* const src = sorted;
  const std::size_t end = bound[c + 1];
  const std::size_t min_count = min_pts;
  const std::int64_t lo0 = g.lo[0];
  const std::int64_t lo1 = g.lo[1];
  const std::int64_t lo2 = g.lo[2];
  const unsigned shift_x = sx;
  const unsigned shift_y = sy;
  const std::uint64_t mask_y = ymask;
  const std::uint64_t mask_z = zmask;
  for (std::size_t lo = bound[c], hi = 0; lo < end; lo = hi) {
    const std::uint64_t key = src[lo] >> 32U;
    for (hi = lo + 1; hi < end && (src[hi] >> 32U) == key; ++hi) {
    }
    const std::size_t cnt = hi - lo;
    if (cnt < min_count) continue;
    out_key[3 * row] = static_cast<std::int64_t>(key >> shift_x) + lo0;
    out_key[3 * row + 1] = static_cast<std::int64_t>((key >> shift_y) & mask_y) + lo1;
    out_key[3 * row + 2] = static_cast<std::int64_t>(key & mask_z) + lo2;
    out_n[row] = static_cast<std::uint32_t>(cnt);
    const auto first = static_cast<std::uint32_t>(src[lo]);
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
      const Eigen::Vector3f p = cloud::point(cloud, static_cast<std::uint32_t>(src[k]));
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
      const auto i = static_cast<std::uint32_t>(src[k]);
      const double d = member_sq_dist(cloud::point(cloud, i), mx, my, mz);
      best = d < best_d ? i : best;  // strict: the first (lowest input index) wins ties
      best_d = d < best_d ? d : best_d;
    }
    out_c[3 * row] = static_cast<float>(mx);
    out_c[3 * row + 1] = static_cast<float>(my);
    out_c[3 * row + 2] = static_cast<float>(mz);
    out_rep[row] = best;
    ++row;
  }
}

/// Sparse path, pass 4: the output rows from the sorted (key << 32 | index) pairs (kNoKey pairs,
/// the non-finite points, last).
template <PointCloud C>
void voxel_rows_sorted(const C& cloud, const VoxelGridParams& params, int threads, const KeyGrid& g,
                       const std::array<int, 3>& b, const std::uint64_t* sorted,
                       VoxelGridWorkspace& ws, VoxelGridResult& r) {
  const std::size_t n = cloud::size(cloud);
  const std::size_t m = n - r.num_non_finite;
  const auto chunks = static_cast<std::size_t>(std::max(1, threads));
  // Pass 4: voxels are runs of equal keys among the m finite points. Chunks start at voxel
  // boundaries; each fills its rows from its first row on (sums in input order: identical for
  // any thread count).
  const std::uint32_t min_pts = params.min_points;
  ws.runs.assign(3 * chunks + 2, 0);
  std::size_t* bound = ws.runs.data();                // chunk c covers [bound[c], bound[c + 1])
  std::size_t* offset = ws.runs.data() + chunks + 1;  // first output row of chunk c
  std::size_t* chunk_dropped = ws.runs.data() + 2 * chunks + 2;  // points dropped by chunk c
  for (std::size_t c = 0; c < chunks; ++c) {
    std::size_t s = chunk_range(m, chunks, c).first;
    while (s > 0 && s < m && (sorted[s] >> 32U) == (sorted[s - 1] >> 32U)) ++s;
    bound[c] = std::max(s, c == 0 ? 0 : bound[c - 1]);
  }
  bound[chunks] = m;
  // Rows and dropped points of chunk c, so that the outputs are allocated once at their exact
  // size (allocating for every point and trimming made glibc return and re-fault the pages: 10x
  // the page faults per call).
  auto count_chunk = [&](std::size_t c) {
    const std::size_t end = bound[c + 1];
    std::size_t kept = 0;
    std::size_t dropped = 0;
    if (min_pts == 1) {  // rows = key changes (vectorises)
      for (std::size_t k = bound[c] + 1; k < end; ++k) {
        kept += (sorted[k] >> 32U) != (sorted[k - 1] >> 32U) ? 1 : 0;
      }
      offset[c + 1] = end > bound[c] ? kept + 1 : 0;
      return dropped;
    }
    for (std::size_t lo = bound[c], hi = 0; lo < end; lo = hi) {
      const std::uint64_t key = sorted[lo] >> 32U;
      for (hi = lo + 1; hi < end && (sorted[hi] >> 32U) == key; ++hi) {
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
  parallel_chunks(chunks, chunks, threads, [&](std::size_t cb, std::size_t ce, std::size_t) {
    for (std::size_t c = cb; c < ce; ++c) chunk_dropped[c] = count_chunk(c);
  });
  for (std::size_t c = 0; c < chunks; ++c) r.num_dropped += chunk_dropped[c];
  offset[0] = 0;
  for (std::size_t c = 0; c < chunks; ++c) offset[c + 1] += offset[c];
  const std::size_t rows = offset[chunks];
  r.centroids.resize(static_cast<Eigen::Index>(rows), 3);
  r.keys.resize(static_cast<Eigen::Index>(rows), 3);
  const bool append = min_pts == 1 && chunks == 1;  // sparse_rows appends to reserved vectors
  if (append) {
    r.counts.reserve(rows);
    r.representative.reserve(rows);
  } else {
    r.counts.resize(rows);
    r.representative.resize(rows);
  }
  parallel_chunks(chunks, chunks, threads, [&](std::size_t cb, std::size_t ce, std::size_t) {
    for (std::size_t c = cb; c < ce; ++c) {
      if (min_pts == 1) {
        sparse_rows(cloud, c, g, b, sorted, bound, offset[c], append, r);
      } else {
        fill_sorted_rows(cloud, c, g, b, sorted, bound, offset, min_pts, r);
      }
    }
  });
}

}  // namespace ds3d::detail
