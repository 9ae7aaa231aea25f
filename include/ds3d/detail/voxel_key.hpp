// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Integer voxel keys: the exact floor(v / leaf) of the fixture spec and the packed-key pass that
// computes them for a whole cloud. Not API. Built on them: sort_by_voxel (voxel_sort.hpp), the
// key-sorted ordering shared by voxel_grid's general path and radius_outlier, and voxel_grid's
// own key-box passes (voxel_grid_keys.hpp).
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

/// Fast path of packed_keys_block: a field is key + 2^20 (kPackOff), kept in [1, 2^21 - 3]
/// (kPackLo, kPackHi) with its remainder more than kPackTol from an integer.
inline constexpr double kPackOff = 1048576.0;
inline constexpr double kPackLo = 1.0;
inline constexpr double kPackHi = 2097150.0;
inline constexpr double kPackTol = 0x1p-28;

#if defined(__SSE2__)
/// The SSE2 part of packed_keys_block: words, redo flags (bad, num_bad) and float bounds (mn,
/// mx) of the block's points four at a time. Returns the first point left to the portable loop.
inline std::size_t packed_keys_sse2(KeyKernel& k, std::size_t len, const std::array<double, 3>& inv,
                                    std::uint8_t* bad, unsigned& num_bad, std::array<float, 3>& mn,
                                    std::array<float, 3>& mx) {
  constexpr double kOff = kPackOff;
  constexpr double kHi = kPackHi;
  constexpr double kTol = kPackTol;
  constexpr float kInf = std::numeric_limits<float>::infinity();
  std::size_t j0 = 0;
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
  return j0;
}
#endif

/// The points of packed_keys_block flagged in `bad` (block from input index b), redone one by
/// one: a non-finite point is counted and marked kNonFiniteKey (or thrown on), the others keyed
/// by fast_voxel_index. Returns whether a non-finite point was met.
inline bool redo_packed_keys(KeyKernel& k, std::size_t b, std::size_t len, const std::uint8_t* bad,
                             const std::array<double, 3>& leaf, const std::array<double, 3>& inv,
                             NonFinite on_non_finite, const char* function) {
  constexpr std::int64_t kHalf = PackedKeyInfo::kHalf;
  bool has_non_finite = false;
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
  return has_non_finite;
}

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
  constexpr double kOff = kPackOff;
  constexpr double kLo = kPackLo;
  constexpr double kHi = kPackHi;
  constexpr double kTol = kPackTol;
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
  j0 = packed_keys_sse2(k, len, inv, bad, num_bad, mn, mx);
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
  const bool has_non_finite =
      num_bad != 0 && redo_packed_keys(k, b, len, bad, leaf, inv, on_non_finite, function);
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

}  // namespace ds3d::detail

// Last: the parts built on the keys (each includes this header first).
#include "ds3d/detail/voxel_grid_keys.hpp"
#include "ds3d/detail/voxel_sort.hpp"
