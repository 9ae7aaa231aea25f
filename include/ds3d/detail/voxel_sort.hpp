// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Key-sorted ordering of a cloud's finite points (stable LSD radix sorts over the used key
// bits; a comparison sort when the keys need more than 64 bits), shared by voxel_grid's general
// path and radius_outlier's neighbour grid. Not API.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <type_traits>
#include <vector>

#include "ds3d/cloud.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/errors.hpp"

namespace ds3d::detail {

/// Finite points of a cloud sorted by voxel key; cells are contiguous runs.
struct VoxelSort {
  std::vector<std::uint32_t> index;       ///< input indices, sorted by (key, index)
  std::vector<std::uint32_t> cell_begin;  ///< start of each cell in `index`, then index.size()
  std::vector<std::array<std::int64_t, 3>> cell_key;  ///< (ix, iy, iz) of each cell, ascending
  std::size_t num_non_finite = 0;
  [[nodiscard]] std::size_t num_cells() const { return cell_key.size(); }
};

/// Stable LSD radix sort of 64-bit words by their bits [lo, lo + bits).
inline void radix_sort_words(std::vector<std::uint64_t>& a, int lo, int bits) {
  if (bits <= 0 || a.size() < 2) return;
  const int passes = (bits + 10) / 11;
  const int digit = (bits + passes - 1) / passes;
  const std::size_t buckets = std::size_t{1} << digit;
  const std::uint64_t mask = buckets - 1;
  std::vector<std::uint64_t> tmp(a.size());
  std::vector<std::uint32_t> count(buckets * static_cast<std::size_t>(passes), 0U);
  for (const std::uint64_t w : a) {  // all histograms in one read
    for (int p = 0; p < passes; ++p) {
      ++count[static_cast<std::size_t>(p) * buckets + ((w >> (lo + p * digit)) & mask)];
    }
  }
  for (int p = 0; p < passes; ++p) {
    std::uint32_t* c = count.data() + static_cast<std::size_t>(p) * buckets;
    std::uint32_t sum = 0;
    for (std::size_t b = 0; b < buckets; ++b) {
      const std::uint32_t t = c[b];
      c[b] = sum;
      sum += t;
    }
    const int shift = lo + p * digit;
    for (const std::uint64_t w : a) tmp[c[(w >> shift) & mask]++] = w;
    a.swap(tmp);
  }
}

/// Stable LSD radix sort of `order` by key[k] (parallel arrays), over the low `bits` bits.
inline void radix_sort_by_key(std::vector<std::uint64_t>& key, std::vector<std::uint32_t>& order,
                              int bits) {
  constexpr int kDigit = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kDigit;
  const std::size_t n = order.size();
  std::vector<std::uint64_t> k1(n);
  std::vector<std::uint32_t> tmp(n);
  std::vector<std::uint32_t> count(kBuckets);
  for (int shift = 0; shift < bits; shift += kDigit) {
    std::fill(count.begin(), count.end(), 0U);
    for (std::size_t i = 0; i < n; ++i) ++count[(key[i] >> shift) & (kBuckets - 1)];
    std::uint32_t sum = 0;
    for (auto& c : count) {
      const std::uint32_t t = c;
      c = sum;
      sum += t;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t dst = count[(key[i] >> shift) & (kBuckets - 1)]++;
      k1[dst] = key[i];
      tmp[dst] = order[i];
    }
    key.swap(k1);
    order.swap(tmp);
  }
}

/// Fills cell_begin / cell_key from a sorted `index` and a same-order cell id sequence.
template <class SameCell, class KeyOf>
void build_cells(VoxelSort& s, SameCell&& same, KeyOf&& key_of) {
  const std::size_t n = s.index.size();
  s.cell_begin.clear();
  s.cell_key.clear();
  s.cell_begin.reserve(n + 1);
  s.cell_key.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (k == 0 || !same(k - 1, k)) {
      s.cell_begin.push_back(static_cast<std::uint32_t>(k));
      s.cell_key.push_back(key_of(k));
    }
  }
  s.cell_begin.push_back(static_cast<std::uint32_t>(n));
}

/// Sorts the finite points of `c` by voxel key (leaf sizes `leaf`, each > 0). The key pass runs
/// on `num_threads`; the sort is serial and stable. Throws InvalidArgument (naming `function`) on
/// a non-finite point under NonFinite::kThrow, a key of magnitude >= 2^62, or >= 2^32 - 1 points.
template <PointCloud C>
[[nodiscard]] VoxelSort sort_by_voxel(const C& c, const std::array<double, 3>& leaf,
                                      NonFinite on_non_finite, int num_threads,
                                      const char* function) {
  const std::size_t n = cloud::size(c);
  DS3D_CHECK(n < std::numeric_limits<std::uint32_t>::max(), function,
             ": clouds are limited to 2^32 - 1 points (got ", n, ")");
  constexpr std::int64_t kHalf = PackedKeyInfo::kHalf;
  constexpr std::uint64_t kNonFinite = kNonFiniteKey;
  const std::array<double, 3> inv{1.0 / leaf[0], 1.0 / leaf[1], 1.0 / leaf[2]};
  const Scratch<std::uint64_t> packed = make_scratch<std::uint64_t>(n);
  const PackedKeyInfo all =
      packed_voxel_keys(c, leaf, on_non_finite, num_threads, function, packed.get());
  VoxelSort s;
  s.num_non_finite = all.non_finite;
  const std::size_t m = n - s.num_non_finite;
  if (m == 0) {
    s.cell_begin.push_back(0);
    return s;
  }

  if (!all.wide) {
    const int bx = bits_for(static_cast<std::uint64_t>(all.hi[0] - all.lo[0]));
    const int by = bits_for(static_cast<std::uint64_t>(all.hi[1] - all.lo[1]));
    const int bz = bits_for(static_cast<std::uint64_t>(all.hi[2] - all.lo[2]));
    const int bits = bx + by + bz;  // <= 63
    const std::uint64_t ox = static_cast<std::uint64_t>(all.lo[0] + kHalf);
    const std::uint64_t oy = static_cast<std::uint64_t>(all.lo[1] + kHalf);
    const std::uint64_t oz = static_cast<std::uint64_t>(all.lo[2] + kHalf);
    const auto sy = static_cast<unsigned>(bz);
    const auto sx = static_cast<unsigned>(by + bz);
    // Compact key: fields relative to their minima, lexicographic order kept.
    auto compact = [&](std::uint64_t w) {
      const std::uint64_t fx = (w >> 42U) - ox;
      const std::uint64_t fy = ((w >> 21U) & 0x1FFFFFU) - oy;
      const std::uint64_t fz = (w & 0x1FFFFFU) - oz;
      return (fx << sx) | (fy << sy) | fz;
    };
    auto decode = [&](std::uint64_t ck) {
      const std::uint64_t mz = (std::uint64_t{1} << bz) - 1;
      const std::uint64_t my = (std::uint64_t{1} << by) - 1;
      return std::array<std::int64_t, 3>{static_cast<std::int64_t>(ck >> sx) + all.lo[0],
                                         static_cast<std::int64_t>((ck >> sy) & my) + all.lo[1],
                                         static_cast<std::int64_t>(ck & mz) + all.lo[2]};
    };
    if (bits <= 32) {
      std::vector<std::uint64_t> pairs;
      pairs.reserve(m);
      for (std::size_t i = 0; i < n; ++i) {
        if (packed[i] == kNonFinite) continue;
        pairs.push_back((compact(packed[i]) << 32U) | i);
      }
      radix_sort_words(pairs, 32, bits);
      s.index.resize(m);
      for (std::size_t k = 0; k < m; ++k) s.index[k] = static_cast<std::uint32_t>(pairs[k]);
      build_cells(
          s, [&](std::size_t a, std::size_t b) { return (pairs[a] >> 32U) == (pairs[b] >> 32U); },
          [&](std::size_t k) { return decode(pairs[k] >> 32U); });
    } else {
      std::vector<std::uint64_t> keys;
      keys.reserve(m);
      s.index.reserve(m);
      for (std::size_t i = 0; i < n; ++i) {
        if (packed[i] == kNonFinite) continue;
        keys.push_back(compact(packed[i]));
        s.index.push_back(static_cast<std::uint32_t>(i));
      }
      radix_sort_by_key(keys, s.index, bits);
      build_cells(
          s, [&](std::size_t a, std::size_t b) { return keys[a] == keys[b]; },
          [&](std::size_t k) { return decode(keys[k]); });
    }
    return s;
  }

  // General path: int64 triples (recomputed; rare: keys beyond ±2^20 voxels).
  std::vector<std::array<std::int64_t, 3>> key(m);
  s.index.resize(m);
  {
    std::size_t k = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (packed[i] == kNonFinite) continue;
      const Eigen::Vector3f p = cloud::point(c, i);
      key[k] = {fast_voxel_index(p.x(), leaf[0], inv[0], function, "x"),
                fast_voxel_index(p.y(), leaf[1], inv[1], function, "y"),
                fast_voxel_index(p.z(), leaf[2], inv[2], function, "z")};
      s.index[k] = static_cast<std::uint32_t>(i);
      ++k;
    }
  }
  std::array<std::int64_t, 3> lo = key[0];
  std::array<std::int64_t, 3> hi = key[0];
  for (const auto& k : key) {
    for (std::size_t d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], k[d]);
      hi[d] = std::max(hi[d], k[d]);
    }
  }
  const int bx = bits_for(static_cast<std::uint64_t>(hi[0] - lo[0]));
  const int by = bits_for(static_cast<std::uint64_t>(hi[1] - lo[1]));
  const int bz = bits_for(static_cast<std::uint64_t>(hi[2] - lo[2]));
  std::vector<std::uint32_t> order(m);
  std::iota(order.begin(), order.end(), 0U);
  if (bx + by + bz <= 64) {
    std::vector<std::uint64_t> pk(m);
    const auto sx = static_cast<unsigned>(by + bz);
    const auto sy = static_cast<unsigned>(bz);
    for (std::size_t k = 0; k < m; ++k) {
      const auto ux = static_cast<std::uint64_t>(key[k][0] - lo[0]);
      const auto uy = static_cast<std::uint64_t>(key[k][1] - lo[1]);
      const auto uz = static_cast<std::uint64_t>(key[k][2] - lo[2]);
      // A shift by 64 is undefined; an axis with 0 bits contributes 0 anyway.
      pk[k] = (sx < 64 ? ux << sx : 0U) | (sy < 64 ? uy << sy : 0U) | uz;
    }
    radix_sort_by_key(pk, order, bx + by + bz);
  } else {
    std::stable_sort(order.begin(), order.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
  }
  std::vector<std::uint32_t> sorted_index(m);
  for (std::size_t k = 0; k < m; ++k) sorted_index[k] = s.index[order[k]];
  s.index.swap(sorted_index);
  build_cells(
      s, [&](std::size_t a, std::size_t b) { return key[order[a]] == key[order[b]]; },
      [&](std::size_t k) { return key[order[k]]; });
  return s;
}

}  // namespace ds3d::detail
