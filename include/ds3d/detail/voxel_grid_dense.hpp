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

#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_grid_rows.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"

namespace ds3d::detail {

/// x / d for x < 2^32 by a double reciprocal, corrected to the exact quotient.
struct FastDiv {
  std::uint64_t d;
  double inv;
  explicit FastDiv(std::uint64_t divisor) : d(divisor), inv(1.0 / static_cast<double>(divisor)) {}
  [[nodiscard]] std::uint64_t operator()(std::uint64_t x) const {
    auto q = static_cast<std::uint64_t>(static_cast<double>(x) * inv);
    if (q * d > x) {
      --q;
    } else if ((q + 1) * d <= x) {
      ++q;
    }
    return q;
  }
};

/// Pass 2 of the dense path: every point's key into cell[0, n) (kNoKey for non-finite points,
/// skipped when `skip`) and the occupancy bitmap occ. Keys in parallel; the bitmap is serial.
template <PointCloud C>
void dense_keys(const C& cloud, int threads, const KeyGrid& g, bool skip, std::uint32_t* cell,
                std::uint64_t* occ) {
  constexpr const char* kFn = "ds3d::voxel_grid";
  const std::size_t n = cloud::size(cloud);
  auto mark = [occ, skip](const std::uint32_t* keys, std::size_t len) {
    if (skip) {
      for (std::size_t j = 0; j < len; ++j) {
        const std::uint32_t k = keys[j];
        if (k != kNoKey) occ[k >> 6U] |= std::uint64_t{1} << (k & 63U);
      }
    } else {
      for (std::size_t j = 0; j < len; ++j) {
        occ[keys[j] >> 6U] |= std::uint64_t{1} << (keys[j] & 63U);
      }
    }
  };
  if (threads == 1) {
    for_each_key_block(cloud, 0, n, g, kFn,
                       [&](std::size_t s, std::size_t len, const std::uint32_t* keys) {
                         std::copy(keys, keys + len, cell + s);
                         mark(keys, len);
                       });
  } else {
    parallel_chunks(n, static_cast<std::size_t>(threads), threads,
                    [&](std::size_t b, std::size_t e, std::size_t) {
                      for_each_key_block(
                          cloud, b, e, g, kFn,
                          [&](std::size_t s, std::size_t len, const std::uint32_t* keys) {
                            std::copy(keys, keys + len, cell + s);
                          });
                    });
    mark(cell, n);
  }
}

/// Pass 3 of the dense path: each point's key in cell replaced by its row (the set bits of occ
/// before it, from rank), and its coordinates added to the row's sums in acc (4 per row) in input
/// order (= the sorted path's order), counted in cnt. kSkip: cell holds kNoKey entries.
template <bool kSkip, PointCloud C>
void dense_sums(const C& cloud, std::uint32_t* cell, const std::uint64_t* const occ_c,
                const std::uint32_t* const rank_c, double* const acc, std::uint32_t* const cnt) {
  const std::size_t n = cloud::size(cloud);
  // Both passes read the points through xyz_block (a plain pointer for contiguous clouds, so the
  // loops need not reload the cloud's data pointer after every store).
  alignas(64) float buf[3 * kKeyBlock];
  for (std::size_t s = 0; s < n; s += kKeyBlock) {
    const std::size_t len = std::min(n - s, kKeyBlock);
    const float* xyz = xyz_block(cloud, s, s + len, buf);
    std::uint32_t* blk = cell + s;
    for (std::size_t j = 0; j < len; ++j) {
      const std::uint32_t k = blk[j];
      if constexpr (kSkip) {
        if (k == kNoKey) continue;
      }
      const std::uint64_t below = occ_c[k >> 6U] & ((std::uint64_t{1} << (k & 63U)) - 1);
      const std::uint32_t row = rank_c[k >> 6U] + static_cast<std::uint32_t>(std::popcount(below));
      blk[j] = row;
      double* a = acc + 4 * std::size_t{row};
      a[0] += xyz[3 * j];
      a[1] += xyz[3 * j + 1];
      a[2] += xyz[3 * j + 2];
      ++cnt[row];
    }
  }
}

/// Pass 4 of the dense path: rep[row] = the first member (input order) nearest the row's mean
/// (acc). Distances are >= 0, so their bit patterns order like the values: an integer compare
/// applied with masks, no branch on the unpredictable "is it nearer" (g++ 12 compiled
/// `c ? i : rep[row]` into one: 112k mispredictions per call at 300k points / 0.05 m, 13k with
/// the masks). kSkip: cell holds kNoKey entries.
template <bool kSkip, PointCloud C>
void dense_representatives(const C& cloud, const std::uint32_t* cell, const double* const acc,
                           std::uint64_t* const best, std::uint32_t* const rep) {
  const std::size_t n = cloud::size(cloud);
  alignas(64) float buf[3 * kKeyBlock];
  for (std::size_t s = 0; s < n; s += kKeyBlock) {
    const std::size_t len = std::min(n - s, kKeyBlock);
    const float* xyz = xyz_block(cloud, s, s + len, buf);
    const std::uint32_t* blk = cell + s;
    for (std::size_t j = 0; j < len; ++j) {
      const std::uint32_t row = blk[j];
      if constexpr (kSkip) {
        if (row == kNoKey) continue;
      }
      const double* a = acc + 4 * std::size_t{row};
      const Eigen::Vector3f p(xyz[3 * j], xyz[3 * j + 1], xyz[3 * j + 2]);
      const auto d = std::bit_cast<std::uint64_t>(member_sq_dist(p, a[0], a[1], a[2]));
      const std::uint64_t old = best[row];
      const std::uint32_t old_rep = rep[row];
      // strict: earlier members win ties
      const std::uint64_t take = std::uint64_t{0} - static_cast<std::uint64_t>(d < old);
      best[row] = old ^ ((old ^ d) & take);
      rep[row] = old_rep ^
                 ((old_rep ^ static_cast<std::uint32_t>(s + j)) & static_cast<std::uint32_t>(take));
    }
  }
}

/// Outputs of the dense path in key order (set bits of occ, `words` words, in ascending order),
/// dropping voxels below min_points: centroids from acc and keys decoded from the bit index;
/// counts and representatives compacted in place.
inline void dense_outputs(const VoxelGridParams& params, const KeyGrid& g,
                          const std::array<std::uint64_t, 3>& range, std::size_t words,
                          const std::uint64_t* occ, const double* acc, std::size_t voxels,
                          VoxelGridResult& r) {
  std::uint32_t* const cnt = r.counts.data();
  std::uint32_t* const rep = r.representative.data();
  // Outputs in key order (set bits in ascending order), dropping voxels below min_points.
  std::size_t rows = voxels;
  if (params.min_points > 1) {
    rows = 0;
    for (std::size_t v = 0; v < voxels; ++v) {
      if (cnt[v] >= params.min_points) {
        ++rows;
      } else {
        r.num_dropped += cnt[v];
      }
    }
  }
  r.centroids.resize(static_cast<Eigen::Index>(rows), 3);
  r.keys.resize(static_cast<Eigen::Index>(rows), 3);
  float* out_c = r.centroids.data();
  std::int64_t* out_k = r.keys.data();
  const FastDiv div_yz(range[1] * range[2]);
  const FastDiv div_z(range[2]);
  std::size_t out = 0;
  std::size_t v = 0;
  for (std::size_t w = 0; w < words; ++w) {
    for (std::uint64_t bits = occ[w]; bits != 0; bits &= bits - 1, ++v) {
      if (cnt[v] < params.min_points) continue;
      const std::uint64_t k =
          64 * std::uint64_t{w} + static_cast<std::uint64_t>(std::countr_zero(bits));
      const std::uint64_t kx = div_yz(k);
      const std::uint64_t rest = k - kx * div_yz.d;
      const std::uint64_t ky = div_z(rest);
      const double* a = acc + 4 * v;
      out_c[3 * out] = static_cast<float>(a[0]);
      out_c[3 * out + 1] = static_cast<float>(a[1]);
      out_c[3 * out + 2] = static_cast<float>(a[2]);
      out_k[3 * out] = static_cast<std::int64_t>(kx) + g.lo[0];
      out_k[3 * out + 1] = static_cast<std::int64_t>(ky) + g.lo[1];
      out_k[3 * out + 2] = static_cast<std::int64_t>(rest - ky * div_z.d) + g.lo[2];
      cnt[out] = cnt[v];  // out <= v: compaction in place
      rep[out] = rep[v];
      ++out;
    }
  }
  r.counts.resize(rows);
  r.representative.resize(rows);
}

/// Dense-box path of voxel_grid: the key box has at most ~16 cells per point. Keys go into an
/// occupancy bitmap whose prefix popcounts give each voxel its output row in key order; the
/// members are then summed in input order straight into their row (no sort), and a second pass
/// picks the representatives. The sums are those of the sorted path bit for bit (same order).
template <PointCloud C>
void voxel_grid_dense(const C& cloud, const VoxelGridParams& params, int threads, const KeyGrid& g,
                      const std::array<std::uint64_t, 3>& range, std::uint64_t cells,
                      VoxelGridWorkspace& ws, VoxelGridResult& r) {
  const std::size_t n = cloud::size(cloud);
  if (ws.cell_capacity < n) {
    ws.cell = make_scratch<std::uint32_t>(n);
    ws.cell_capacity = n;
  }
  std::uint32_t* cell = ws.cell.get();
  const std::size_t words = static_cast<std::size_t>((cells + 63) / 64);
  ws.occupied.assign(words, 0U);
  std::uint64_t* occ = ws.occupied.data();
  const bool skip = r.num_non_finite > 0;  // kNoKey entries to skip (else no test per point)
  // Pass 2: keys (parallel) and occupancy.
  dense_keys(cloud, threads, g, skip, cell, occ);
  ws.rank.resize(words);
  std::uint32_t* rank = ws.rank.data();
  std::size_t voxels = 0;
  for (std::size_t w = 0; w < words; ++w) {
    rank[w] = static_cast<std::uint32_t>(voxels);
    voxels += static_cast<std::size_t>(std::popcount(occ[w]));
  }
  // Pass 3: each point's row; sums in input order (= the sorted path's order).
  ws.acc.assign(4 * voxels, 0.0);  // sums, then means (one pad)
  double* const acc = ws.acc.data();
  r.counts.assign(voxels, 0U);
  std::uint32_t* const cnt = r.counts.data();
  if (skip) {
    dense_sums<true>(cloud, cell, occ, rank, acc, cnt);
  } else {
    dense_sums<false>(cloud, cell, occ, rank, acc, cnt);
  }
  for (std::size_t v = 0; v < voxels; ++v) {
    double* a = acc + 4 * v;
    const double inv_cnt = 1.0 / static_cast<double>(cnt[v]);
    a[0] *= inv_cnt;
    a[1] *= inv_cnt;
    a[2] *= inv_cnt;
  }
  // Pass 4: representatives: the first member (input order) nearest the mean.
  r.representative.resize(voxels);
  ws.best.assign(voxels, std::bit_cast<std::uint64_t>(std::numeric_limits<double>::infinity()));
  if (skip) {
    dense_representatives<true>(cloud, cell, acc, ws.best.data(), r.representative.data());
  } else {
    dense_representatives<false>(cloud, cell, acc, ws.best.data(), r.representative.data());
  }
  dense_outputs(params, g, range, words, occ, acc, voxels, r);
}

}  // namespace ds3d::detail
