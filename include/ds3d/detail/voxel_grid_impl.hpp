// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::voxel_grid (included by voxel_grid.hpp). Not API.

#include <bit>
#include <cstring>
#include <limits>
#include <type_traits>

#include "ds3d/detail/parallel.hpp"
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

/// Dense-box path of voxel_grid: the key box has at most ~16 cells per point. Keys go into an
/// occupancy bitmap whose prefix popcounts give each voxel its output row in key order; the
/// members are then summed in input order straight into their row (no sort), and a second pass
/// picks the representatives. The sums are those of the sorted path bit for bit (same order).
template <PointCloud C>
void voxel_grid_dense(const C& cloud, const VoxelGridParams& params, int threads, const KeyGrid& g,
                      const std::array<std::uint64_t, 3>& range, std::uint64_t cells,
                      VoxelGridWorkspace& ws, VoxelGridResult& r) {
  constexpr const char* kFn = "ds3d::voxel_grid";
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
  // Pass 2: keys (parallel) and occupancy.
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
  const std::uint64_t* const occ_c = occ;
  const std::uint32_t* const rank_c = rank;
  // Both passes read the points through xyz_block (a plain pointer for contiguous clouds, so the
  // loops need not reload the cloud's data pointer after every store).
  auto sum_pass = [&](auto has_skip) {
    alignas(64) float buf[3 * kKeyBlock];
    for (std::size_t s = 0; s < n; s += kKeyBlock) {
      const std::size_t len = std::min(n - s, kKeyBlock);
      const float* xyz = xyz_block(cloud, s, s + len, buf);
      std::uint32_t* blk = cell + s;
      for (std::size_t j = 0; j < len; ++j) {
        const std::uint32_t k = blk[j];
        if constexpr (decltype(has_skip)::value) {
          if (k == kNoKey) continue;
        }
        const std::uint64_t below = occ_c[k >> 6U] & ((std::uint64_t{1} << (k & 63U)) - 1);
        const std::uint32_t row =
            rank_c[k >> 6U] + static_cast<std::uint32_t>(std::popcount(below));
        blk[j] = row;
        double* a = acc + 4 * std::size_t{row};
        a[0] += xyz[3 * j];
        a[1] += xyz[3 * j + 1];
        a[2] += xyz[3 * j + 2];
        ++cnt[row];
      }
    }
  };
  if (skip) {
    sum_pass(std::true_type{});
  } else {
    sum_pass(std::false_type{});
  }
  for (std::size_t v = 0; v < voxels; ++v) {
    double* a = acc + 4 * v;
    const double inv_cnt = 1.0 / static_cast<double>(cnt[v]);
    a[0] *= inv_cnt;
    a[1] *= inv_cnt;
    a[2] *= inv_cnt;
  }
  // Pass 4: representatives: the first member (input order) nearest the mean. Distances are
  // >= 0, so their bit patterns order like the values: an integer compare applied with masks,
  // no branch on the unpredictable "is it nearer" (g++ 12 compiled `c ? i : rep[row]` into one:
  // 112k mispredictions per call at 300k points / 0.05 m, 13k with the masks).
  r.representative.resize(voxels);
  std::uint32_t* const rep = r.representative.data();
  ws.best.assign(voxels, std::bit_cast<std::uint64_t>(std::numeric_limits<double>::infinity()));
  std::uint64_t* const best = ws.best.data();
  auto rep_pass = [&](auto has_skip) {
    alignas(64) float buf[3 * kKeyBlock];
    for (std::size_t s = 0; s < n; s += kKeyBlock) {
      const std::size_t len = std::min(n - s, kKeyBlock);
      const float* xyz = xyz_block(cloud, s, s + len, buf);
      const std::uint32_t* blk = cell + s;
      for (std::size_t j = 0; j < len; ++j) {
        const std::uint32_t row = blk[j];
        if constexpr (decltype(has_skip)::value) {
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
        rep[row] = old_rep ^ ((old_rep ^ static_cast<std::uint32_t>(s + j)) &
                              static_cast<std::uint32_t>(take));
      }
    }
  };
  if (skip) {
    rep_pass(std::true_type{});
  } else {
    rep_pass(std::false_type{});
  }
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

/// Exclusive prefix sums of c[0, len) in place.
inline void exclusive_prefix(std::uint32_t* c, std::size_t len) {
  std::uint32_t sum = 0;
  for (std::size_t k = 0; k < len; ++k) {
    const std::uint32_t cnt = c[k];
    c[k] = sum;
    sum += cnt;
  }
}

/// Sparse path, keys of 23 to 32 bits: the keys (parallel, into the first half of ws.words)
/// and their stable sort as (key << 32 | index) pairs with the (y, z) fields (`low` bits, at most
/// log2(n) and 22) as one digit and the x field (`bits - low` <= 11 bits) as the other. Returns the
/// buffer holding the sorted pairs.
///
/// A depth frame arrives in sensor order: along an image row the (y, z) voxel moves by one
/// z step at a time (y is proportional to z for a fixed row), so the 2^low-bucket scatter of the
/// first pass writes to a few hundred places that it revisits (good locality) and the sort needs
/// two passes instead of three. In an arbitrary order (a shuffled cloud) that scatter misses the
/// cache at every point; hence the key pass counts the points whose (y, z) digit lies less than
/// one y step from the previous point's, and when fewer than half do, the (y, z) digit is split
/// into two (histograms derived from the joint one) and the sort makes the usual three passes.
/// Same output either way (a stable LSD sort over the same bits).
template <PointCloud C>
[[nodiscard]] const std::uint64_t* sort_pairs_yz_x(const C& cloud, int threads, const KeyGrid& g,
                                                   int bits, unsigned low, unsigned bz,
                                                   VoxelGridWorkspace& ws) {
  constexpr const char* kFn = "ds3d::voxel_grid";
  const std::size_t n = cloud::size(cloud);
  const unsigned high = static_cast<unsigned>(bits) - low;
  const std::size_t n_low = std::size_t{1} << low;
  const std::size_t n_high = std::size_t{1} << high;
  const auto low_mask = static_cast<std::uint32_t>(n_low - 1);
  const auto high_mask = static_cast<std::uint32_t>(n_high - 1);
  const unsigned wa = low / 2;  // fallback digits: [0, wa) and [wa, low), each <= 11 bits
  const std::size_t n_a = std::size_t{1} << wa;
  const std::size_t n_b = std::size_t{1} << (low - wa);
  // One joint and one x histogram per chunk of the (parallel) key pass, summed into chunk 0's.
  const auto chunks = static_cast<std::size_t>(std::max(1, threads));
  const std::size_t per_chunk = n_low + n_high;
  ws.hist.assign(chunks * per_chunk + n_a + n_b, 0U);
  std::uint32_t* const h_low = ws.hist.data();
  std::uint32_t* const h_high = h_low + n_low;
  std::uint32_t* const h_a = ws.hist.data() + chunks * per_chunk;
  std::uint32_t* const h_b = h_a + n_a;
  std::uint64_t* const a = ws.words.get();
  std::uint64_t* const t = ws.tmp.get();
  auto* const key_bytes = reinterpret_cast<unsigned char*>(a);
  // |d| < 2^bz for the (y, z) digit difference d, as one unsigned compare.
  const std::uint32_t step = std::uint32_t{1} << bz;
  ws.runs.assign(chunks, 0);  // points near their predecessor, per chunk
  auto pass_keys = [&](std::size_t b0, std::size_t e0, std::size_t ch) {
    std::uint32_t* const hl = h_low + ch * per_chunk;
    std::uint32_t* const hh = hl + n_low;
    std::size_t near = 0;
    std::uint32_t prev = 0;  // (y, z) digit of the previous block's last point
    for_each_key_block(
        cloud, b0, e0, g, kFn, [&](std::size_t s, std::size_t len, const std::uint32_t* keys) {
          std::memcpy(key_bytes + 4 * s, keys, 4 * len);
          for (std::size_t j = 0; j < len; ++j) {
            const std::uint32_t key = keys[j];
            ++hl[key & low_mask];
            ++hh[(key >> low) & high_mask];
          }
          std::size_t blk_near = ((keys[0] & low_mask) - prev + (step - 1)) < 2 * step - 1 ? 1 : 0;
          for (std::size_t j = 1; j < len; ++j) {  // vectorises
            const std::uint32_t d = (keys[j] & low_mask) - (keys[j - 1] & low_mask);
            blk_near += d + (step - 1) < 2 * step - 1 ? 1 : 0;
          }
          near += blk_near;
          prev = keys[len - 1] & low_mask;
        });
    ws.runs[ch] = near;
  };
  if (chunks == 1) {
    pass_keys(0, n, 0);
  } else {
    parallel_chunks(n, chunks, threads, pass_keys);
    for (std::size_t ch = 1; ch < chunks; ++ch) {
      const std::uint32_t* src = h_low + ch * per_chunk;
      for (std::size_t k = 0; k < per_chunk; ++k) h_low[k] += src[k];  // vectorises
    }
  }
  std::size_t near = 0;
  for (std::size_t ch = 0; ch < chunks; ++ch) near += ws.runs[ch];
  auto key_at = [key_bytes](std::size_t k) {
    std::uint32_t key;
    std::memcpy(&key, key_bytes + 4 * k, 4);
    return key;
  };
  // First pass: pairs (key << 32 | index) placed by the key digit under `mask`; later passes:
  // pairs moved by the digit `shift` bits above the key's lowest bit.
  auto scatter_keys = [&](std::uint64_t* dst, std::uint32_t* h, std::uint32_t mask) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint32_t key = key_at(k);
      dst[h[key & mask]++] = (std::uint64_t{key} << 32U) | k;
    }
  };
  auto scatter_pairs = [n](const std::uint64_t* src, std::uint64_t* dst, std::uint32_t* h,
                           unsigned shift, std::uint32_t mask) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint64_t w = src[k];
      dst[h[(w >> (32U + shift)) & mask]++] = w;
    }
  };
  exclusive_prefix(h_high, n_high);
  if (2 * near >= n) {  // sensor order: two passes, (y, z) then x
    exclusive_prefix(h_low, n_low);
    scatter_keys(t, h_low, low_mask);
    scatter_pairs(t, a, h_high, low, high_mask);
    return a;
  }
  // Arbitrary order: three passes; the histograms of the two (y, z) digits are the row and column
  // sums of the joint one (contiguous rows of 2^wa counters: vectorised adds).
  for (std::size_t row = 0; row < n_b; ++row) {
    const std::uint32_t* src = h_low + (row << wa);
    std::uint32_t sum = 0;
    for (std::size_t i = 0; i < n_a; ++i) {
      h_a[i] += src[i];
      sum += src[i];
    }
    h_b[row] = sum;
  }
  exclusive_prefix(h_a, n_a);
  exclusive_prefix(h_b, n_b);
  const auto mask_a = static_cast<std::uint32_t>(n_a - 1);
  const auto mask_b = static_cast<std::uint32_t>(n_b - 1);
  scatter_keys(t, h_a, mask_a);
  scatter_pairs(t, a, h_b, wa, mask_b);
  scatter_pairs(a, t, h_high, low, high_mask);
  return t;
}

/// Sparse path, general digits: keys (parallel) with all radix histograms, then a stable LSD
/// radix sort over the used bits in 0 to 3 passes of equal digits (<= 11 bits). Returns the
/// buffer holding the sorted pairs.
template <PointCloud C>
[[nodiscard]] const std::uint64_t* sort_pairs_digits(const C& cloud, int threads, const KeyGrid& g,
                                                     int bits, VoxelGridWorkspace& ws) {
  constexpr const char* kFn = "ds3d::voxel_grid";
  const std::size_t n = cloud::size(cloud);
  const int passes = (bits + 10) / 11;
  const int digit = passes == 0 ? 0 : (bits + passes - 1) / passes;
  const std::size_t buckets = std::size_t{1} << digit;
  const std::uint64_t dmask = buckets - 1;
  // Pass 2: 32-bit keys (stored in the first half of `a`, read back as bytes: the buffer is
  // typed uint64) and all radix histograms (always three: a pass beyond `passes` sees only zero
  // bits, so the counting loop has no inner loop), one set per chunk.
  const auto chunks = static_cast<std::size_t>(std::max(1, threads));
  ws.hist.assign(buckets * 3 * chunks, 0U);
  std::uint64_t* a = ws.words.get();
  std::uint64_t* const t = ws.tmp.get();
  auto* const key_bytes = reinterpret_cast<unsigned char*>(a);
  auto pass_keys = [&](std::size_t b0, std::size_t e0, std::size_t ch) {
    std::uint32_t* h = ws.hist.data() + 3 * buckets * ch;
    for_each_key_block(cloud, b0, e0, g, kFn,
                       [&](std::size_t s, std::size_t len, const std::uint32_t* keys) {
                         std::memcpy(key_bytes + 4 * s, keys, 4 * len);
                         for (std::size_t j = 0; j < len; ++j) {
                           const std::uint32_t key = keys[j];
                           ++h[key & dmask];
                           ++h[buckets + ((key >> digit) & dmask)];
                           ++h[2 * buckets + ((key >> (2 * digit)) & dmask)];
                         }
                       });
  };
  if (chunks == 1) {
    pass_keys(0, n, 0);
  } else {
    parallel_chunks(n, chunks, threads, pass_keys);
    for (std::size_t ch = 1; ch < chunks; ++ch) {
      for (std::size_t k = 0; k < 3 * buckets; ++k) {
        ws.hist[k] += ws.hist[3 * buckets * ch + k];
      }
    }
  }
  // Pass 3: stable radix sort over the used bits only (0 to 3 passes); kNoKey pairs end last.
  // Its first pass reads the keys and writes (key << 32 | index) pairs into t.
  const std::uint64_t* sorted = t;
  {
    std::uint32_t* c = ws.hist.data();
    std::uint32_t sum = 0;
    for (std::size_t k = 0; k < buckets; ++k) {
      const std::uint32_t cnt = c[k];
      c[k] = sum;
      sum += cnt;
    }
    const std::uint64_t mask = passes == 0 ? 0 : dmask;  // no pass: one bucket, input order
    for (std::size_t k = 0; k < n; ++k) {
      std::uint32_t key;
      std::memcpy(&key, key_bytes + 4 * k, 4);
      t[c[key & mask]++] = (std::uint64_t{key} << 32U) | k;
    }
    if (passes > 1) {
      sorted = radix_sort_pairs(t, a, n, ws.hist.data() + buckets, passes - 1, digit, 32 + digit);
    }
  }
  return sorted;
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
  const auto sx = static_cast<unsigned>(b[1] + b[2]);
  const auto sy = static_cast<unsigned>(b[2]);
  const std::uint64_t zmask = (std::uint64_t{1} << b[2]) - 1;
  const std::uint64_t ymask = (std::uint64_t{1} << b[1]) - 1;
  // Fills the rows of chunk c from offset[c] on. (Everything read in the loop is a local copy:
  // the int64 / size_t output stores could otherwise alias it.)
  auto fill_chunk = [&](std::size_t c) {
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
        fill_chunk(c);
      }
    }
  });
}

/// Sparse-box path of voxel_grid: (key << 32 | index) pairs, bit-packed keys of `bits` <= 32
/// bits (kNoKey, all ones, sorts last), stable LSD radix sort, then one row per run of equal keys.
template <PointCloud C>
void voxel_grid_sorted(const C& cloud, const VoxelGridParams& params, int threads, const KeyGrid& g,
                       const std::array<int, 3>& b, int bits, VoxelGridWorkspace& ws,
                       VoxelGridResult& r) {
  const std::size_t n = cloud::size(cloud);
  if (ws.capacity < n) {  // default-initialised: no zero-fill of buffers written before read
    ws.words = make_scratch<std::uint64_t>(n);
    ws.tmp = make_scratch<std::uint64_t>(n);
    ws.capacity = n;
  }
  // Passes 2 and 3: keys, then their stable radix sort as pairs (kNoKey pairs end last). Where
  // three equal digits would be needed (23 to 32 bits): when the (y, z) fields fit in a digit of
  // at most 22 bits (its fallback halves are <= 11 bits, like every other digit) whose counters,
  // one set per thread, take no more memory than the keys (chunks * 2^low <= n), and the x field
  // in one of at most 11, the two-digit split of sort_pairs_yz_x.
  const int passes = (bits + 10) / 11;
  const auto low = static_cast<unsigned>(b[1] + b[2]);  // bits of the (y, z) fields
  const auto chunks = static_cast<std::size_t>(std::max(1, threads));
  const bool yz_x = passes == 3 && bits - static_cast<int>(low) <= 11 && low <= 22 &&
                    chunks * (std::size_t{1} << low) <= n;
  const std::uint64_t* const sorted =
      yz_x ? sort_pairs_yz_x(cloud, threads, g, bits, low, static_cast<unsigned>(b[2]), ws)
           : sort_pairs_digits(cloud, threads, g, bits, ws);
  voxel_rows_sorted(cloud, params, threads, g, b, sorted, ws, r);
}

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
