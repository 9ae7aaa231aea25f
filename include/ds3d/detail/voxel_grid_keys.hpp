// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// voxel_grid's own key passes: the exact key box of a cloud's finite points and 32-bit keys
// relative to it, block by block (AVX2 where available). Not API.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <type_traits>
#include <vector>

#if defined(__AVX2__)
#include <immintrin.h>
#endif

#include "ds3d/cloud.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/errors.hpp"

namespace ds3d::detail {

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

/// The shipped clouds that hold doubles and are read as float (cloud.hpp).
template <class C>
inline constexpr bool kReadsDoubleAsFloat =
    std::is_same_v<C, Points3d> || std::is_same_v<C, Eigen::Ref<const Points3d>>;

/// A finite double beyond the float range reads as ±inf and would vanish among the non-finite
/// points without a word; this names the first one. Called only when non-finite points were seen.
template <PointCloud C>
void check_float_range(const C& c, const char* function) {
  if constexpr (kReadsDoubleAsFloat<C>) {
    const std::array<const char*, 3> axis{"x", "y", "z"};
    for (Eigen::Index i = 0; i < c.rows(); ++i) {
      for (Eigen::Index j = 0; j < 3; ++j) {
        const double v = c(i, j);
        DS3D_CHECK(!std::isfinite(v) || std::isfinite(static_cast<float>(v)), function,
                   ": points: row ", i, " ", axis[static_cast<std::size_t>(j)], " = ", v,
                   " is finite but beyond the float32 range (|v| <= ",
                   std::numeric_limits<float>::max(), ") in which points are read");
      }
    }
  }
}

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
  if (fb.non_finite > 0) check_float_range(c, function);
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

}  // namespace ds3d::detail
