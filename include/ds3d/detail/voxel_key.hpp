// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Integer voxel keys and a key-sorted ordering of points, shared by voxel_grid (one centroid per
// voxel) and radius_outlier (a neighbour grid with cell size R). Not API.
//
// A point's voxel is (floor(x/dx), floor(y/dy), floor(z/dz)) with the division in double (the
// spec in tests/data/preprocess/README.md). When the occupied key ranges fit in 64 bits, the
// three keys are packed (offset by their minima) into one uint64 whose order is lexicographic on
// (ix, iy, iz), and sorted with a stable LSD radix sort over the used bits only; otherwise a
// stable comparison sort on the triples is used. Stability keeps the members of each voxel in
// input order, which makes sums (and so centroids) independent of the thread count.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

#include "ds3d/cloud.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/errors.hpp"

namespace ds3d::detail {

/// Largest |key| accepted: keeps key ± 1 and max - min representable in int64.
inline constexpr double kMaxVoxelKey = 4611686018427387904.0;  // 2^62

/// Finite points of a cloud in structure-of-arrays form, with their input indices.
struct FinitePoints {
  std::vector<float> x, y, z;
  std::vector<std::uint32_t> index;  ///< input row of each stored point
  std::size_t num_non_finite = 0;
  [[nodiscard]] std::size_t size() const { return index.size(); }
};

/// Copies the finite points of `c` (SoA) and counts the others; throws when `on_non_finite` is
/// kThrow and one is found, or when the cloud has more than 2^32 - 1 points.
template <PointCloud C>
[[nodiscard]] FinitePoints gather_finite(const C& c, NonFinite on_non_finite,
                                         const char* function) {
  const std::size_t n = cloud::size(c);
  DS3D_CHECK(n < std::numeric_limits<std::uint32_t>::max(), function,
             ": clouds are limited to 2^32 - 1 points (got ", n, ")");
  FinitePoints f;
  f.x.reserve(n);
  f.y.reserve(n);
  f.z.reserve(n);
  f.index.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f p = cloud::point(c, i);
    if (!cloud::is_finite(p)) {
      DS3D_CHECK(on_non_finite != NonFinite::kThrow, function, ": point ", i,
                 " is not finite (", p.x(), ", ", p.y(), ", ", p.z(), ")");
      ++f.num_non_finite;
      continue;
    }
    f.x.push_back(p.x());
    f.y.push_back(p.y());
    f.z.push_back(p.z());
    f.index.push_back(static_cast<std::uint32_t>(i));
  }
  return f;
}

/// Voxel keys of every point of `f` and the order that sorts them lexicographically (stable).
struct SortedKeys {
  std::vector<std::int64_t> ix, iy, iz;  ///< key of point k of FinitePoints (unsorted)
  std::vector<std::uint32_t> order;      ///< positions into FinitePoints, sorted by key
  std::vector<std::uint32_t> cell_begin;  ///< start of each distinct key in `order`, + end
};

/// floor(v / leaf) as int64, checked against overflow (names `function` and the value).
[[nodiscard]] inline std::int64_t voxel_index(float v, double leaf, const char* function,
                                              const char* axis) {
  const double q = std::floor(static_cast<double>(v) / leaf);
  DS3D_CHECK(std::abs(q) < kMaxVoxelKey, function, ": voxel index ", q, " of coordinate ", axis,
             " = ", v, " with leaf size ", leaf, " overflows the signed 64-bit key range");
  return static_cast<std::int64_t>(q);
}

/// Stable LSD radix sort of `order` by `key[order[k]]`, over the low `bits` bits of the keys.
inline void radix_sort_by_key(const std::vector<std::uint64_t>& key,
                              std::vector<std::uint32_t>& order, int bits) {
  constexpr int kDigit = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kDigit;
  const std::size_t n = order.size();
  std::vector<std::uint64_t> k0(n), k1(n);
  std::vector<std::uint32_t> tmp(n);
  for (std::size_t i = 0; i < n; ++i) k0[i] = key[order[i]];
  std::vector<std::uint32_t> count(kBuckets);
  for (int shift = 0; shift < bits; shift += kDigit) {
    std::fill(count.begin(), count.end(), 0U);
    for (std::size_t i = 0; i < n; ++i) ++count[(k0[i] >> shift) & (kBuckets - 1)];
    std::uint32_t sum = 0;
    for (auto& c : count) {
      const std::uint32_t t = c;
      c = sum;
      sum += t;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t b = (k0[i] >> shift) & (kBuckets - 1);
      const std::uint32_t dst = count[b]++;
      k1[dst] = k0[i];
      tmp[dst] = order[i];
    }
    k0.swap(k1);
    order.swap(tmp);
  }
}

/// Number of bits needed to store values in [0, range].
[[nodiscard]] inline int bits_for(std::uint64_t range) {
  int b = 0;
  while (b < 64 && (range >> b) != 0) ++b;
  return b;
}

/// Computes the voxel key of each point of `f` (leaf sizes `leaf`, > 0) and sorts them.
/// Key computation runs on `num_threads`; the sort is serial and stable (deterministic).
[[nodiscard]] inline SortedKeys sort_by_voxel(const FinitePoints& f, const std::array<double, 3>& leaf,
                                              int num_threads, const char* function) {
  const std::size_t n = f.size();
  SortedKeys s;
  s.ix.resize(n);
  s.iy.resize(n);
  s.iz.resize(n);
  const std::size_t chunks = static_cast<std::size_t>(std::max(1, num_threads));
  std::vector<std::array<std::int64_t, 6>> bounds(chunks);
  parallel_chunks(n, chunks, num_threads, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::array<std::int64_t, 6> bb{std::numeric_limits<std::int64_t>::max(),
                                   std::numeric_limits<std::int64_t>::max(),
                                   std::numeric_limits<std::int64_t>::max(),
                                   std::numeric_limits<std::int64_t>::min(),
                                   std::numeric_limits<std::int64_t>::min(),
                                   std::numeric_limits<std::int64_t>::min()};
    const double lx = leaf[0];
    const double ly = leaf[1];
    const double lz = leaf[2];
    for (std::size_t i = b; i < e; ++i) {
      const double qx = std::floor(static_cast<double>(f.x[i]) / lx);
      const double qy = std::floor(static_cast<double>(f.y[i]) / ly);
      const double qz = std::floor(static_cast<double>(f.z[i]) / lz);
      if (!(std::abs(qx) < kMaxVoxelKey && std::abs(qy) < kMaxVoxelKey &&
            std::abs(qz) < kMaxVoxelKey)) {
        // Slow path only to build the message naming the offending value.
        (void)voxel_index(f.x[i], lx, function, "x");
        (void)voxel_index(f.y[i], ly, function, "y");
        (void)voxel_index(f.z[i], lz, function, "z");
      }
      const auto kx = static_cast<std::int64_t>(qx);
      const auto ky = static_cast<std::int64_t>(qy);
      const auto kz = static_cast<std::int64_t>(qz);
      s.ix[i] = kx;
      s.iy[i] = ky;
      s.iz[i] = kz;
      bb[0] = std::min(bb[0], kx);
      bb[1] = std::min(bb[1], ky);
      bb[2] = std::min(bb[2], kz);
      bb[3] = std::max(bb[3], kx);
      bb[4] = std::max(bb[4], ky);
      bb[5] = std::max(bb[5], kz);
    }
    bounds[c] = bb;
  });
  s.order.resize(n);
  std::iota(s.order.begin(), s.order.end(), 0U);
  if (n == 0) {
    s.cell_begin.push_back(0);
    return s;
  }
  std::array<std::int64_t, 6> bb = bounds[0];
  for (const auto& o : bounds) {
    for (int d = 0; d < 3; ++d) {
      bb[static_cast<std::size_t>(d)] = std::min(bb[static_cast<std::size_t>(d)], o[static_cast<std::size_t>(d)]);
      bb[static_cast<std::size_t>(d + 3)] =
          std::max(bb[static_cast<std::size_t>(d + 3)], o[static_cast<std::size_t>(d + 3)]);
    }
  }
  const auto rx = static_cast<std::uint64_t>(bb[3] - bb[0]);
  const auto ry = static_cast<std::uint64_t>(bb[4] - bb[1]);
  const auto rz = static_cast<std::uint64_t>(bb[5] - bb[2]);
  const int bx = bits_for(rx);
  const int by = bits_for(ry);
  const int bz = bits_for(rz);
  if (bx + by + bz <= 64) {
    std::vector<std::uint64_t> packed(n);
    const auto shift_x = static_cast<unsigned>(by + bz);
    const auto shift_y = static_cast<unsigned>(bz);
    for (std::size_t i = 0; i < n; ++i) {
      const auto ux = static_cast<std::uint64_t>(s.ix[i] - bb[0]);
      const auto uy = static_cast<std::uint64_t>(s.iy[i] - bb[1]);
      const auto uz = static_cast<std::uint64_t>(s.iz[i] - bb[2]);
      // A shift by 64 is undefined; an axis with 0 bits contributes 0 anyway.
      packed[i] = (shift_x < 64 ? ux << shift_x : 0U) | (shift_y < 64 ? uy << shift_y : 0U) | uz;
    }
    radix_sort_by_key(packed, s.order, bx + by + bz);
  } else {
    std::stable_sort(s.order.begin(), s.order.end(), [&](std::uint32_t a, std::uint32_t b) {
      if (s.ix[a] != s.ix[b]) return s.ix[a] < s.ix[b];
      if (s.iy[a] != s.iy[b]) return s.iy[a] < s.iy[b];
      return s.iz[a] < s.iz[b];
    });
  }
  s.cell_begin.push_back(0);
  for (std::size_t k = 1; k < n; ++k) {
    const std::uint32_t a = s.order[k - 1];
    const std::uint32_t b = s.order[k];
    if (s.ix[a] != s.ix[b] || s.iy[a] != s.iy[b] || s.iz[a] != s.iz[b]) {
      s.cell_begin.push_back(static_cast<std::uint32_t>(k));
    }
  }
  s.cell_begin.push_back(static_cast<std::uint32_t>(n));
  return s;
}

}  // namespace ds3d::detail
