// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Integer voxel keys and a key-sorted ordering of a cloud's finite points, shared by voxel_grid
// (one centroid per voxel) and radius_outlier (a neighbour grid with cell size R). Not API.
// voxel_grid's own passes (key box, 32-bit box-relative keys) are voxel_box, grid_keys_block
// and for_each_key_block below; sort_by_voxel is the general path and radius_outlier's.
//
// A point's voxel is (floor(x/dx), floor(y/dy), floor(z/dz)) with a correctly rounded division
// in double (the fixture spec). The hot loop multiplies by 1/dx instead and falls back to the
// division only when the product lies within a few ulps of an integer, where the two could
// disagree; the keys are therefore exactly those of the division. Keys are packed into one
// integer whose order is lexicographic on (ix, iy, iz), and sorted with a stable LSD radix sort
// over the used bits only: (key << 32 | index) pairs when the key needs <= 32 bits, else
// separate 64-bit keys. Keys beyond ±2^20 per axis take a general path (int64 triples, packed
// when they fit in 64 bits, else a comparison sort). Stability keeps each voxel's members in
// input order, so per-voxel sums and the output do not depend on the thread count.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <vector>

#include <cstdlib>
#include <new>
#include <type_traits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__AVX2__)
#include <immintrin.h>
#endif
#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "ds3d/cloud.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/errors.hpp"

namespace ds3d::detail {

/// Frees scratch memory from make_scratch().
struct ScratchFree {
  void operator()(void* p) const noexcept { std::free(p); }
};
/// Uninitialised scratch array (see make_scratch()).
template <class T>
using Scratch = std::unique_ptr<T[], ScratchFree>;

/// Uninitialised scratch array of n trivial elements. Blocks of 2 MB or more are 2 MB-aligned and,
/// on Linux, advised for transparent huge pages (MADV_HUGEPAGE; a hint, ignored where THP is
/// off): a fresh block is then faulted in per 2 MB rather than per 4 KB page. On the benchmark VM
/// the 4 KB faults of the two 2.4 MB sort buffers cost ~9 ms per call at 300k points, more than
/// the sort itself.
template <class T>
[[nodiscard]] Scratch<T> make_scratch(std::size_t n) {
  static_assert(std::is_trivial_v<T>);
  constexpr std::size_t kHuge = std::size_t{2} << 20U;
  const std::size_t bytes = std::max<std::size_t>(n, 1) * sizeof(T);
  void* p = nullptr;
  if (bytes >= kHuge) {
    const std::size_t size = (bytes + kHuge - 1) / kHuge * kHuge;
    p = std::aligned_alloc(kHuge, size);
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (p != nullptr) (void)madvise(p, size, MADV_HUGEPAGE);
#endif
  } else {
    p = std::malloc(bytes);
  }
  if (p == nullptr) throw std::bad_alloc();
  return Scratch<T>(static_cast<T*>(p));
}

/// Largest |key| accepted: keeps key ± 1 and max - min representable in int64.
inline constexpr double kMaxVoxelKey = 4611686018427387904.0;  // 2^62

/// Finite points of a cloud sorted by voxel key; cells are contiguous runs.
struct VoxelSort {
  std::vector<std::uint32_t> index;       ///< input indices, sorted by (key, index)
  std::vector<std::uint32_t> cell_begin;  ///< start of each cell in `index`, then index.size()
  std::vector<std::array<std::int64_t, 3>> cell_key;  ///< (ix, iy, iz) of each cell, ascending
  std::size_t num_non_finite = 0;
  [[nodiscard]] std::size_t num_cells() const { return cell_key.size(); }
};

/// floor(v / leaf) as in the spec (double division), checked against overflow.
[[nodiscard]] inline std::int64_t exact_voxel_index(float v, double leaf, const char* function,
                                                    const char* axis) {
  const double q = std::floor(static_cast<double>(v) / leaf);
  DS3D_CHECK(std::abs(q) < kMaxVoxelKey, function, ": voxel index ", q, " of coordinate ", axis,
             " = ", v, " with leaf size ", leaf, " overflows the signed 64-bit key range");
  return static_cast<std::int64_t>(q);
}

/// Same value as exact_voxel_index, faster: multiply by inv = 1/leaf; redo with the division
/// when the product is within 2^-49 relative of an integer (both are within 2 ulps of the
/// exact quotient, so elsewhere their floors agree).
[[nodiscard]] inline std::int64_t fast_voxel_index(float v, double leaf, double inv,
                                                   const char* function, const char* axis) {
  const double q = static_cast<double>(v) * inv;
  if (!(std::abs(q) < 2305843009213693952.0)) {  // 2^61, or NaN: exact path names the value
    return exact_voxel_index(v, leaf, function, axis);
  }
  auto t = static_cast<std::int64_t>(q);  // truncation
  double ft = static_cast<double>(t);
  if (q < ft) {
    t -= 1;
    ft -= 1.0;
  }
  const double frac = q - ft;  // exact, in [0, 1]
  const double tol = std::abs(q) * 0x1p-49 + 0x1p-60;
  if (frac <= tol || frac >= 1.0 - tol) return exact_voxel_index(v, leaf, function, axis);
  return t;
}

/// Number of bits needed to store values in [0, range].
[[nodiscard]] inline int bits_for(std::uint64_t range) {
  int b = 0;
  while (b < 64 && (range >> b) != 0) ++b;
  return b;
}

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

/// Bounds and counts of a packed key pass (packed_voxel_keys).
struct PackedKeyInfo {
  static constexpr std::int64_t kHalf = std::int64_t{1} << 20;  // fast path: |key| < 2^20
  std::array<std::int64_t, 3> lo{kHalf, kHalf, kHalf};          ///< per-axis minimum key
  std::array<std::int64_t, 3> hi{-kHalf, -kHalf, -kHalf};       ///< per-axis maximum key
  std::size_t non_finite = 0;                                   ///< points marked kNonFiniteKey
  bool wide = false;  ///< some |key| >= 2^20: the packed words are not valid, use int64 keys

  /// Merges the bounds and counts of another chunk.
  void merge(const PackedKeyInfo& o) {
    non_finite += o.non_finite;
    wide = wide || o.wide;
    for (std::size_t d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], o.lo[d]);
      hi[d] = std::max(hi[d], o.hi[d]);
    }
  }
};

/// Marks a non-finite point in the packed key array.
inline constexpr std::uint64_t kNonFiniteKey = ~std::uint64_t{0};

/// Packs three keys, each in [-2^20, 2^20), as 21-bit fields (offset 2^20) whose integer order is
/// lexicographic on (ix, iy, iz).
[[nodiscard]] inline std::uint64_t pack_key(std::int64_t k0, std::int64_t k1, std::int64_t k2) {
  constexpr std::int64_t kHalf = PackedKeyInfo::kHalf;
  return (static_cast<std::uint64_t>(k0 + kHalf) & 0x1FFFFFU) << 42U |
         (static_cast<std::uint64_t>(k1 + kHalf) & 0x1FFFFFU) << 21U |
         (static_cast<std::uint64_t>(k2 + kHalf) & 0x1FFFFFU);
}

/// Points per block of the key kernel: the block's buffers stay in L1.
inline constexpr std::size_t kKeyBlock = 256;

/// Per-chunk state of the key kernel: one block of coordinates and packed words, and the float
/// bounds of the blocks that held no non-finite point (floor is monotonic, so the keys of these
/// bounds are the bounds of the keys).
struct KeyKernel {
  alignas(64) float x[kKeyBlock];
  alignas(64) float y[kKeyBlock];
  alignas(64) float z[kKeyBlock];
  alignas(64) std::uint64_t word[kKeyBlock + 1];  ///< packed key or kNonFiniteKey; +1 sentinel
  std::array<float, 3> fmin{std::numeric_limits<float>::infinity(),
                            std::numeric_limits<float>::infinity(),
                            std::numeric_limits<float>::infinity()};
  std::array<float, 3> fmax{-std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity()};
  PackedKeyInfo info;  ///< bounds of the keys of the other blocks, counts, wide flag
};

/// Packed keys of points [b, e) of `c` (e - b <= kKeyBlock) into k.word[0, e - b).
///
/// The keys are exactly floor(v / leaf) of the spec. The branch-free (vectorisable) loop computes
/// q = v * (1/leaf) + 2^20 in double and truncates it: q is within 2^-31 of the exact quotient
/// + 2^20 (two roundings of at most 2^-32 and 2^-33 for |key| < 2^20), so its floor is the exact
/// floor unless q is within 2^-31 of an integer. Points within 2^-28 of a voxel boundary, out of
/// range or non-finite are redone one by one (fast_voxel_index: division when needed).
template <PointCloud C>
void packed_keys_block(const C& c, std::size_t b, std::size_t e, const std::array<double, 3>& leaf,
                       const std::array<double, 3>& inv, NonFinite on_non_finite,
                       const char* function, KeyKernel& k) {
  constexpr double kOff = 1048576.0;  // 2^20: a field is key + 2^20
  constexpr double kLo = 1.0;         // fields in [1, 2^21 - 3] on the fast path
  constexpr double kHi = 2097150.0;
  constexpr double kTol = 0x1p-28;
  constexpr std::int64_t kHalf = PackedKeyInfo::kHalf;
  const std::size_t len = e - b;
  for (std::size_t j = 0; j < len; ++j) {  // structure of arrays
    const Eigen::Vector3f p = cloud::point(c, b + j);
    k.x[j] = p.x();
    k.y[j] = p.y();
    k.z[j] = p.z();
  }
  alignas(64) std::uint8_t bad[kKeyBlock / 4];  // bit j % 4 of bad[j / 4]: redo point j
  unsigned num_bad = 0;
  std::size_t j0 = 0;
  constexpr float kInf = std::numeric_limits<float>::infinity();
  std::array<float, 3> mn{kInf, kInf, kInf};  // bounds of this block (valid if all finite)
  std::array<float, 3> mx{-kInf, -kInf, -kInf};
#if defined(__SSE2__)
  // Four points per step (SSE2 is part of x86-64). cvttpd2dq returns INT_MIN for NaN, inf and
  // out-of-range values, which then fail the field range test; a negative quotient truncates
  // upwards, so its remainder is <= 0 and fails the tolerance test: both are redone below.
  {
    const __m128d off = _mm_set1_pd(kOff);
    const __m128d tol = _mm_set1_pd(kTol);
    const __m128d one_tol = _mm_set1_pd(1.0 - kTol);
    const __m128i zero = _mm_setzero_si128();
    const __m128i lim = _mm_set1_epi32(static_cast<std::int32_t>(kHi));
    auto axis = [&](const float* src, __m128d inv_leaf, __m128i& t, __m128& good, __m128& lo,
                    __m128& hi) {
      const __m128 v = _mm_load_ps(src);
      lo = _mm_min_ps(v, lo);  // a NaN in v keeps lo (second operand); inf: block discarded
      hi = _mm_max_ps(v, hi);
      const __m128d q_lo = _mm_add_pd(_mm_mul_pd(_mm_cvtps_pd(v), inv_leaf), off);
      const __m128d q_hi = _mm_add_pd(_mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(v, v)), inv_leaf), off);
      const __m128i t_lo = _mm_cvttpd_epi32(q_lo);
      const __m128i t_hi = _mm_cvttpd_epi32(q_hi);
      const __m128d r_lo = _mm_sub_pd(q_lo, _mm_cvtepi32_pd(t_lo));
      const __m128d r_hi = _mm_sub_pd(q_hi, _mm_cvtepi32_pd(t_hi));
      const __m128d g_lo = _mm_and_pd(_mm_cmpgt_pd(r_lo, tol), _mm_cmplt_pd(r_lo, one_tol));
      const __m128d g_hi = _mm_and_pd(_mm_cmpgt_pd(r_hi, tol), _mm_cmplt_pd(r_hi, one_tol));
      t = _mm_unpacklo_epi64(t_lo, t_hi);
      const __m128i in_range = _mm_and_si128(_mm_cmpgt_epi32(t, zero), _mm_cmplt_epi32(t, lim));
      good = _mm_and_ps(_mm_shuffle_ps(_mm_castpd_ps(g_lo), _mm_castpd_ps(g_hi), 0x88),
                        _mm_castsi128_ps(in_range));
    };
    const __m128d v0 = _mm_set1_pd(inv[0]);
    const __m128d v1 = _mm_set1_pd(inv[1]);
    const __m128d v2 = _mm_set1_pd(inv[2]);
    __m128 lo0 = _mm_set1_ps(kInf), lo1 = lo0, lo2 = lo0;
    __m128 hi0 = _mm_set1_ps(-kInf), hi1 = hi0, hi2 = hi0;
    for (; j0 + 4 <= len; j0 += 4) {
      __m128i t0, t1, t2;
      __m128 g0, g1, g2;
      axis(k.x + j0, v0, t0, g0, lo0, hi0);
      axis(k.y + j0, v1, t1, g1, lo1, hi1);
      axis(k.z + j0, v2, t2, g2, lo2, hi2);
      const auto m = static_cast<unsigned>(_mm_movemask_ps(_mm_and_ps(_mm_and_ps(g0, g1), g2)));
      bad[j0 / 4] = static_cast<std::uint8_t>(m ^ 0xFU);
      num_bad |= m ^ 0xFU;
      const __m128i w_lo =
          _mm_or_si128(_mm_or_si128(_mm_slli_epi64(_mm_unpacklo_epi32(t0, zero), 42),
                                    _mm_slli_epi64(_mm_unpacklo_epi32(t1, zero), 21)),
                       _mm_unpacklo_epi32(t2, zero));
      const __m128i w_hi =
          _mm_or_si128(_mm_or_si128(_mm_slli_epi64(_mm_unpackhi_epi32(t0, zero), 42),
                                    _mm_slli_epi64(_mm_unpackhi_epi32(t1, zero), 21)),
                       _mm_unpackhi_epi32(t2, zero));
      _mm_store_si128(reinterpret_cast<__m128i*>(k.word + j0), w_lo);
      _mm_store_si128(reinterpret_cast<__m128i*>(k.word + j0 + 2), w_hi);
    }
    alignas(16) float l[3][4];
    alignas(16) float h[3][4];
    _mm_store_ps(l[0], lo0);
    _mm_store_ps(l[1], lo1);
    _mm_store_ps(l[2], lo2);
    _mm_store_ps(h[0], hi0);
    _mm_store_ps(h[1], hi1);
    _mm_store_ps(h[2], hi2);
    for (std::size_t d = 0; d < 3; ++d) {
      mn[d] = std::min({l[d][0], l[d][1], l[d][2], l[d][3]});
      mx[d] = std::max({h[d][0], h[d][1], h[d][2], h[d][3]});
    }
  }
#endif
  for (std::size_t j = j0; j < len; ++j) {  // portable path; the tail of a block on x86-64
    double q0 = static_cast<double>(k.x[j]) * inv[0] + kOff;
    double q1 = static_cast<double>(k.y[j]) * inv[1] + kOff;
    double q2 = static_cast<double>(k.z[j]) * inv[2] + kOff;
    const bool ok = q0 > kLo && q0 < kHi && q1 > kLo && q1 < kHi && q2 > kLo && q2 < kHi;
    q0 = ok ? q0 : 2.5;  // keep the conversions defined (NaN, inf, out of range)
    q1 = ok ? q1 : 2.5;
    q2 = ok ? q2 : 2.5;
    const auto t0 = static_cast<std::int32_t>(q0);  // truncation = floor (q > 0)
    const auto t1 = static_cast<std::int32_t>(q1);
    const auto t2 = static_cast<std::int32_t>(q2);
    const double r0 = q0 - static_cast<double>(t0);
    const double r1 = q1 - static_cast<double>(t1);
    const double r2 = q2 - static_cast<double>(t2);
    const bool good = ok && r0 > kTol && r0 < 1.0 - kTol && r1 > kTol && r1 < 1.0 - kTol &&
                      r2 > kTol && r2 < 1.0 - kTol;
    k.word[j] = static_cast<std::uint64_t>(static_cast<std::uint32_t>(t0)) << 42U |
                static_cast<std::uint64_t>(static_cast<std::uint32_t>(t1)) << 21U |
                static_cast<std::uint64_t>(static_cast<std::uint32_t>(t2));
    mn = {std::min(mn[0], k.x[j]), std::min(mn[1], k.y[j]), std::min(mn[2], k.z[j])};
    mx = {std::max(mx[0], k.x[j]), std::max(mx[1], k.y[j]), std::max(mx[2], k.z[j])};
    if (j % 4 == 0) bad[j / 4] = 0;
    if (!good) {
      bad[j / 4] = static_cast<std::uint8_t>(bad[j / 4] | (1U << (j % 4)));
      num_bad = 1;
    }
  }
  bool has_non_finite = false;
  if (num_bad != 0) {
    for (std::size_t j = 0; j < len; ++j) {
      if (((bad[j / 4] >> (j % 4)) & 1U) == 0) continue;
      const Eigen::Vector3f p(k.x[j], k.y[j], k.z[j]);
      if (!cloud::is_finite(p)) {
        DS3D_CHECK(on_non_finite != NonFinite::kThrow, function, ": point ", b + j,
                   " is not finite (", p.x(), ", ", p.y(), ", ", p.z(), ")");
        ++k.info.non_finite;
        has_non_finite = true;
        k.word[j] = kNonFiniteKey;
        continue;
      }
      const std::int64_t k0 = fast_voxel_index(p.x(), leaf[0], inv[0], function, "x");
      const std::int64_t k1 = fast_voxel_index(p.y(), leaf[1], inv[1], function, "y");
      const std::int64_t k2 = fast_voxel_index(p.z(), leaf[2], inv[2], function, "z");
      k.info.wide = k.info.wide || k0 < -kHalf || k0 >= kHalf || k1 < -kHalf || k1 >= kHalf ||
                    k2 < -kHalf || k2 >= kHalf;
      k.word[j] = pack_key(k0, k1, k2);
    }
  }
  if (!has_non_finite) {  // common case: float bounds (a NaN may have been skipped: see above)
    for (std::size_t d = 0; d < 3; ++d) {
      k.fmin[d] = std::min(k.fmin[d], mn[d]);
      k.fmax[d] = std::max(k.fmax[d], mx[d]);
    }
    return;
  }
  for (std::size_t j = 0; j < len; ++j) {
    const std::uint64_t w = k.word[j];
    if (w == kNonFiniteKey) continue;
    const std::array<std::int64_t, 3> key{static_cast<std::int64_t>(w >> 42U) - kHalf,
                                          static_cast<std::int64_t>((w >> 21U) & 0x1FFFFFU) - kHalf,
                                          static_cast<std::int64_t>(w & 0x1FFFFFU) - kHalf};
    for (std::size_t d = 0; d < 3; ++d) {
      k.info.lo[d] = std::min(k.info.lo[d], key[d]);
      k.info.hi[d] = std::max(k.info.hi[d], key[d]);
    }
  }
}

/// Final bounds and counts of a chunk processed by packed_keys_block.
[[nodiscard]] inline PackedKeyInfo finish_key_kernel(const KeyKernel& k,
                                                     const std::array<double, 3>& leaf,
                                                     const std::array<double, 3>& inv,
                                                     const char* function) {
  PackedKeyInfo info = k.info;
  if (!info.wide && k.fmin[0] <= k.fmax[0]) {  // some block without non-finite points
    const std::array<const char*, 3> axis{"x", "y", "z"};
    for (std::size_t d = 0; d < 3; ++d) {
      info.lo[d] =
          std::min(info.lo[d], fast_voxel_index(k.fmin[d], leaf[d], inv[d], function, axis[d]));
      info.hi[d] =
          std::max(info.hi[d], fast_voxel_index(k.fmax[d], leaf[d], inv[d], function, axis[d]));
    }
  }
  return info;
}

/// One pass over the cloud: out[i] = the voxel key of point i packed by pack_key, or
/// kNonFiniteKey; returns the per-axis key bounds. The keys are exactly floor(v / leaf) of the
/// spec (see packed_keys_block). Runs on `num_threads`; throws like sort_by_voxel. `out` must
/// hold cloud::size(c) words.
template <PointCloud C>
[[nodiscard]] PackedKeyInfo packed_voxel_keys(const C& c, const std::array<double, 3>& leaf,
                                              NonFinite on_non_finite, int num_threads,
                                              const char* function, std::uint64_t* packed) {
  const std::size_t n = cloud::size(c);
  const std::array<double, 3> inv{1.0 / leaf[0], 1.0 / leaf[1], 1.0 / leaf[2]};
  auto body = [&](std::size_t b, std::size_t e, PackedKeyInfo& out) {
    KeyKernel k;  // ~4 KB on the stack: no allocation
    for (std::size_t s = b; s < e; s += kKeyBlock) {
      const std::size_t t = std::min(e, s + kKeyBlock);
      packed_keys_block(c, s, t, leaf, inv, on_non_finite, function, k);
      std::copy(k.word, k.word + (t - s), packed + s);
    }
    out = finish_key_kernel(k, leaf, inv, function);
  };
  PackedKeyInfo all;
  const auto chunks = static_cast<std::size_t>(std::max(1, num_threads));
  if (chunks == 1) {
    body(0, n, all);
    return all;
  }
  std::vector<PackedKeyInfo> info(chunks);
  parallel_chunks(n, chunks, num_threads,
                  [&](std::size_t b, std::size_t e, std::size_t ch) { body(b, e, info[ch]); });
  for (const auto& ci : info) all.merge(ci);
  return all;
}

/// Interleaved float xyz of points [b, e) of `c` (e - b <= kKeyBlock): a pointer into the cloud
/// when it stores them so (row-major float matrices with 3 floats per row), else a copy in `buf`.
template <PointCloud C>
[[nodiscard]] const float* xyz_block(const C& c, std::size_t b, std::size_t e, float* buf) {
  if constexpr (std::is_same_v<C, Points3f>) {
    return c.data() + 3 * b;
  } else {
    if constexpr (std::is_same_v<C, Eigen::Ref<const Points3f>>) {
      if (c.outerStride() == 3) return c.data() + 3 * b;
    }
    for (std::size_t j = 0; j < e - b; ++j) {
      const Eigen::Vector3f p = cloud::point(c, b + j);
      buf[3 * j] = p.x();
      buf[3 * j + 1] = p.y();
      buf[3 * j + 2] = p.z();
    }
    return buf;
  }
}

/// Float bounds of the finite points of a range, the number of non-finite ones and the first of
/// them (input index).
struct FloatBounds {
  std::array<float, 3> lo{std::numeric_limits<float>::infinity(),
                          std::numeric_limits<float>::infinity(),
                          std::numeric_limits<float>::infinity()};
  std::array<float, 3> hi{-std::numeric_limits<float>::infinity(),
                          -std::numeric_limits<float>::infinity(),
                          -std::numeric_limits<float>::infinity()};
  std::size_t non_finite = 0;
  std::size_t first_non_finite = std::numeric_limits<std::size_t>::max();
  /// Merges the bounds and counts of another range.
  void merge(const FloatBounds& o) {
    for (std::size_t d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], o.lo[d]);
      hi[d] = std::max(hi[d], o.hi[d]);
    }
    non_finite += o.non_finite;
    first_non_finite = std::min(first_non_finite, o.first_non_finite);
  }
};

/// Adds points [0, len) of an interleaved xyz block (input indices from `base`) to `fb`.
inline void bounds_block(const float* xyz, std::size_t len, std::size_t base, FloatBounds& fb) {
  std::size_t j = 0;
#if defined(__AVX2__)
  // Eight points = three registers; lane l of register k holds axis (8k + l) mod 3. Any
  // non-finite value sends the whole block to the per-point loop below.
  if (len >= 8) {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    __m256 mn[3] = {_mm256_set1_ps(kInf), _mm256_set1_ps(kInf), _mm256_set1_ps(kInf)};
    __m256 mx[3] = {_mm256_set1_ps(-kInf), _mm256_set1_ps(-kInf), _mm256_set1_ps(-kInf)};
    __m256 bad = _mm256_setzero_ps();
    const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7FFFFFFF));
    const __m256 inf = _mm256_set1_ps(kInf);
    for (; j + 8 <= len; j += 8) {
      for (int k = 0; k < 3; ++k) {
        const __m256 a = _mm256_loadu_ps(xyz + 3 * j + 8 * static_cast<std::size_t>(k));
        mn[k] = _mm256_min_ps(mn[k], a);
        mx[k] = _mm256_max_ps(mx[k], a);
        bad = _mm256_or_ps(bad, _mm256_cmp_ps(_mm256_and_ps(a, abs_mask), inf, _CMP_NLT_UQ));
      }
    }
    if (_mm256_movemask_ps(bad) == 0) {
      alignas(32) float l[3][8];
      alignas(32) float h[3][8];
      for (int k = 0; k < 3; ++k) {
        _mm256_store_ps(l[k], mn[k]);
        _mm256_store_ps(h[k], mx[k]);
      }
      for (std::size_t k = 0; k < 3; ++k) {
        for (std::size_t lane = 0; lane < 8; ++lane) {
          const std::size_t d = (8 * k + lane) % 3;
          fb.lo[d] = std::min(fb.lo[d], l[k][lane]);
          fb.hi[d] = std::max(fb.hi[d], h[k][lane]);
        }
      }
    } else {
      j = 0;
    }
  }
#endif
  for (; j < len; ++j) {
    const float x = xyz[3 * j];
    const float y = xyz[3 * j + 1];
    const float z = xyz[3 * j + 2];
    if (std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) {
      fb.lo = {std::min(fb.lo[0], x), std::min(fb.lo[1], y), std::min(fb.lo[2], z)};
      fb.hi = {std::max(fb.hi[0], x), std::max(fb.hi[1], y), std::max(fb.hi[2], z)};
    } else {
      fb.first_non_finite = std::min(fb.first_non_finite, base + j);
      ++fb.non_finite;
    }
  }
}

/// Exact key box of a cloud's finite points: per-axis minimum and maximum voxel index.
struct VoxelBox {
  std::array<std::int64_t, 3> lo{};  ///< minimum key per axis
  std::array<std::int64_t, 3> hi{};  ///< maximum key per axis
  std::size_t non_finite = 0;        ///< non-finite points (ignored)
};

/// One streaming pass over the cloud (parallel): the key box of its finite points. floor is
/// monotonic, so the keys of the float extremes are the extreme keys. Throws like sort_by_voxel
/// (a non-finite point under kThrow: the first one is named; a key of magnitude >= 2^62).
template <PointCloud C>
[[nodiscard]] VoxelBox voxel_box(const C& c, const std::array<double, 3>& leaf,
                                 NonFinite on_non_finite, int num_threads, const char* function) {
  const std::size_t n = cloud::size(c);
  auto body = [&](std::size_t b, std::size_t e, FloatBounds& out) {
    alignas(64) float buf[3 * kKeyBlock];
    for (std::size_t s = b; s < e; s += kKeyBlock) {
      const std::size_t t = std::min(e, s + kKeyBlock);
      bounds_block(xyz_block(c, s, t, buf), t - s, s, out);
    }
  };
  FloatBounds fb;
  const auto chunks = static_cast<std::size_t>(std::max(1, num_threads));
  if (chunks == 1) {
    body(0, n, fb);
  } else {
    std::vector<FloatBounds> part(chunks);
    parallel_chunks(n, chunks, num_threads,
                    [&](std::size_t b, std::size_t e, std::size_t ch) { body(b, e, part[ch]); });
    for (const auto& p : part) fb.merge(p);
  }
  if (fb.non_finite > 0 && on_non_finite == NonFinite::kThrow) {
    const Eigen::Vector3f p = cloud::point(c, fb.first_non_finite);
    DS3D_CHECK(false, function, ": point ", fb.first_non_finite, " is not finite (", p.x(), ", ",
               p.y(), ", ", p.z(), ")");
  }
  VoxelBox box;
  box.non_finite = fb.non_finite;
  if (fb.non_finite == n) return box;
  const std::array<const char*, 3> axis{"x", "y", "z"};
  for (std::size_t d = 0; d < 3; ++d) {
    box.lo[d] = exact_voxel_index(fb.lo[d], leaf[d], function, axis[d]);
    box.hi[d] = exact_voxel_index(fb.hi[d], leaf[d], function, axis[d]);
  }
  return box;
}

/// Key of a non-finite point in grid_keys_block (never a valid key: see KeyGrid).
inline constexpr std::uint32_t kNoKey = 0xFFFFFFFFU;

/// 32-bit keys relative to a key box: key = (ix - lo_x) * mul_x + (iy - lo_y) * mul_y + (iz -
/// lo_z), lexicographic on (ix, iy, iz) when mul_y > max(iz - lo_z) and mul_x > max of the rest.
/// Used when every |key| < 2^21 and the largest key is below kNoKey.
struct KeyGrid {
  std::array<double, 3> leaf{};        ///< leaf sizes
  std::array<double, 3> inv{};         ///< 1 / leaf
  std::array<std::int64_t, 3> lo{};    ///< key box minimum
  std::array<std::uint32_t, 3> mul{};  ///< field multipliers (mul[2] = 1)
};

/// Keys of points [0, len) of an interleaved xyz block into keys[0, len); kNoKey for non-finite
/// points. Exactly floor(v / leaf) - lo of the spec: q = v * (1/leaf) - lo in double is within
/// 2^-30 of the exact quotient - lo (|key| < 2^21: product and inverse each within 2^-32, the
/// subtraction within 2^-31), so its truncation is the exact floor unless q is within 2^-28 of
/// an integer (or negative, or not finite); those points are redone with the division.
inline void grid_keys_block(const float* xyz, std::size_t len, const KeyGrid& g,
                            const char* function, std::uint32_t* keys) {
  constexpr double kTol = 0x1p-28;
  auto redo = [&](std::size_t j) {
    const float x = xyz[3 * j];
    const float y = xyz[3 * j + 1];
    const float z = xyz[3 * j + 2];
    if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) {
      keys[j] = kNoKey;
      return;
    }
    const auto kx = static_cast<std::uint32_t>(
        fast_voxel_index(x, g.leaf[0], g.inv[0], function, "x") - g.lo[0]);
    const auto ky = static_cast<std::uint32_t>(
        fast_voxel_index(y, g.leaf[1], g.inv[1], function, "y") - g.lo[1]);
    const auto kz = static_cast<std::uint32_t>(
        fast_voxel_index(z, g.leaf[2], g.inv[2], function, "z") - g.lo[2]);
    keys[j] = kx * g.mul[0] + ky * g.mul[1] + kz;
  };
  std::size_t j = 0;
#if defined(__AVX2__)
  {
    // Deinterleave eight points (three loads, two blends and one permute per axis).
    const __m256i px = _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5);
    const __m256i py = _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6);
    const __m256i pz = _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7);
    const __m256d tol = _mm256_set1_pd(kTol);
    const __m256d one_tol = _mm256_set1_pd(1.0 - kTol);
    const __m256d inv[3] = {_mm256_set1_pd(g.inv[0]), _mm256_set1_pd(g.inv[1]),
                            _mm256_set1_pd(g.inv[2])};
    const __m256d lo[3] = {_mm256_set1_pd(static_cast<double>(g.lo[0])),
                           _mm256_set1_pd(static_cast<double>(g.lo[1])),
                           _mm256_set1_pd(static_cast<double>(g.lo[2]))};
    const __m256i mul_x = _mm256_set1_epi32(static_cast<std::int32_t>(g.mul[0]));
    const __m256i mul_y = _mm256_set1_epi32(static_cast<std::int32_t>(g.mul[1]));
    // Field of 8 coordinates and a mask (bit l: lane l is safe).
    auto field = [&](__m256 v, int d, __m256i& t) {
      const __m256d q0 =
          _mm256_sub_pd(_mm256_mul_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(v)), inv[d]), lo[d]);
      const __m256d q1 =
          _mm256_sub_pd(_mm256_mul_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(v, 1)), inv[d]), lo[d]);
      const __m128i t0 = _mm256_cvttpd_epi32(q0);  // INT_MIN for NaN, inf, out of range
      const __m128i t1 = _mm256_cvttpd_epi32(q1);
      const __m256d r0 = _mm256_sub_pd(q0, _mm256_cvtepi32_pd(t0));
      const __m256d r1 = _mm256_sub_pd(q1, _mm256_cvtepi32_pd(t1));
      const __m256d g0 =
          _mm256_and_pd(_mm256_cmp_pd(r0, tol, _CMP_GT_OQ), _mm256_cmp_pd(r0, one_tol, _CMP_LT_OQ));
      const __m256d g1 =
          _mm256_and_pd(_mm256_cmp_pd(r1, tol, _CMP_GT_OQ), _mm256_cmp_pd(r1, one_tol, _CMP_LT_OQ));
      t = _mm256_set_m128i(t1, t0);
      return _mm256_movemask_pd(g0) | (_mm256_movemask_pd(g1) << 4);
    };
    for (; j + 8 <= len; j += 8) {
      const float* f = xyz + 3 * j;
      const __m256 a0 = _mm256_loadu_ps(f);
      const __m256 a1 = _mm256_loadu_ps(f + 8);
      const __m256 a2 = _mm256_loadu_ps(f + 16);
      const __m256 vx =
          _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a0, a1, 0x92), a2, 0x24), px);
      const __m256 vy =
          _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a0, a1, 0x24), a2, 0x49), py);
      const __m256 vz =
          _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a0, a1, 0x49), a2, 0x92), pz);
      __m256i tx;
      __m256i ty;
      __m256i tz;
      const int good = field(vx, 0, tx) & field(vy, 1, ty) & field(vz, 2, tz);
      const __m256i key = _mm256_add_epi32(
          _mm256_add_epi32(_mm256_mullo_epi32(tx, mul_x), _mm256_mullo_epi32(ty, mul_y)), tz);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + j), key);
      if (good != 0xFF) {
        for (std::size_t l = 0; l < 8; ++l) {
          if (((static_cast<unsigned>(good) >> l) & 1U) == 0) redo(j + l);
        }
      }
    }
  }
#endif
  for (; j < len; ++j) {  // portable path; the tail of a block with AVX2
    bool ok = true;
    std::uint32_t key = 0;
    for (std::size_t d = 0; d < 3; ++d) {
      const double q =
          static_cast<double>(xyz[3 * j + d]) * g.inv[d] - static_cast<double>(g.lo[d]);
      if (!(q > kTol && q < 4194304.0)) {  // also false for NaN; 2^22 > any field
        ok = false;
        break;
      }
      const auto t = static_cast<std::uint32_t>(q);
      const double r = q - static_cast<double>(t);
      ok = r > kTol && r < 1.0 - kTol;
      if (!ok) break;
      key += t * g.mul[d];
    }
    if (ok) {
      keys[j] = key;
    } else {
      redo(j);
    }
  }
}

/// Calls emit(first, len, keys) for consecutive blocks of points [b, e) with their grid keys.
template <PointCloud C, class Emit>
void for_each_key_block(const C& c, std::size_t b, std::size_t e, const KeyGrid& g,
                        const char* function, Emit&& emit) {
  alignas(64) float buf[3 * kKeyBlock];
  alignas(64) std::uint32_t keys[kKeyBlock];
  for (std::size_t s = b; s < e; s += kKeyBlock) {
    const std::size_t t = std::min(e, s + kKeyBlock);
    grid_keys_block(xyz_block(c, s, t, buf), t - s, g, function, keys);
    emit(s, t - s, static_cast<const std::uint32_t*>(keys));
  }
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
