// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Exact minimum spanning trees of the mutual-reachability graph
// d_mr(i,j) = max{core(i), core(j), d(i,j)}. Not API: see ds3d/cluster/hdbscan.hpp.

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include "ds3d/detail/box_bounds.hpp"
#include "ds3d/detail/kdtree_nd.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/cluster/hdbscan.hpp"

namespace ds3d::detail {

// Which Prim step prim_dense runs. kAuto picks the widest one the CPU runs (AVX-512F, AVX2,
// SSE2 for D = 3; generic otherwise); the others exist so tests can check that every step gives
// bitwise the same tree. A forced step that the build or the CPU cannot run (see
// prim_step_available) falls back to kAuto's choice.
enum class PrimStep : std::uint8_t { kAuto, kGeneric, kSse2, kAvx2, kAvx512 };

// How BoruvkaKdTree finds the core distances (D = 3, k + 1 <= 16): several queries per tree
// walk, one per SIMD lane (kAvx2: 4, kAvx512: 8), or one walk per query (kPerQuery, also used for
// other D and k). kAuto picks the widest the build and the CPU run; a forced mode that cannot run
// falls back to kAuto's choice. All give bitwise the same results (tests run each).
enum class KnnLanes : std::uint8_t { kAuto, kPerQuery, kAvx2, kAvx512 };

// prim_dense keeps its slot count a multiple of this (the widest step's lane count).
inline constexpr std::size_t kPrimPad = 8;

// Prim on the implicit dense graph. The not-yet-connected points are kept in SoA arrays in
// index order; a connected point is retired by setting its key and core to +inf (never updated
// again, never picked) and the arrays are compacted, order-preserving, once an eighth are retired.
// Each step is one streaming pass that updates keys and finds the first minimum (branch-free,
// SSE2 for D = 3). Keys are *squared* mutual-reachability distances max{κ_a², κ_b², d²}: squaring
// is monotone, so no sqrt is needed in the loop; the weight of each chosen edge is then
// recomputed exactly as max{κ_a, κ_b, sqrt(d²)} so MST weights are bitwise those of the
// reference. Ties are resolved like the reference (first point in index order with the smallest
// key; keys only replaced by strictly smaller ones); values that differ only after squaring's
// rounding (≤ 1 ulp) may order differently. O(n² D) time, O(n D) memory.
struct PrimSoA {
  std::size_t dim = 0;
  std::size_t m = 0;               // slots in use
  std::vector<double> buf;         // owns the arrays below (64-byte aligned, one stride apart)
  std::vector<double*> coords;     // [dim][m]
  double* core2 = nullptr;         // κ² (+inf when retired)
  double* key2 = nullptr;          // best squared d_mr so far (+inf when retired)
  double* from = nullptr;          // source point of key2 (exact integer as double)
  std::vector<std::uint32_t> idx;  // point id of each slot

  // Allocates dim + 3 arrays of `slots` doubles. Each starts on a 64-byte line, so whole-vector
  // loads never straddle two lines (unaligned AVX-512 loads from malloc'd memory always do), and
  // consecutive starts lie 640 bytes apart modulo 4 KiB, so a load never falsely waits on a recent
  // store to another array at the same 4 KiB offset. Prim's step is bound by these loads: this
  // layout alone cut it by about 10 % at 2,000 keypoints.
  void allocate(std::size_t slots) {
    constexpr std::size_t kPage = 4096 / sizeof(double);
    constexpr std::size_t kShift = 640 / sizeof(double);
    const std::size_t stride =
        slots <= kShift ? kShift : (slots - kShift + kPage - 1) / kPage * kPage + kShift;
    buf.assign((dim + 3) * stride + 8, 0.0);
    double* p = buf.data();
    p += ((64 - reinterpret_cast<std::uintptr_t>(p) % 64) % 64) / sizeof(double);
    coords.resize(dim);
    for (std::size_t j = 0; j < dim; ++j) coords[j] = p + j * stride;
    core2 = p + dim * stride;
    key2 = core2 + stride;
    from = key2 + stride;
    idx.assign(slots, 0U);
  }
};

// Updates keys with the new tree point (coords c, squared core cc2, id cur) and returns the slot
// with the first smallest key.
inline std::size_t prim_step_generic(PrimSoA& s, const double* c, double cc2, double cur) {
  double best = std::numeric_limits<double>::infinity();
  std::size_t best_t = s.m;
  for (std::size_t t = 0; t < s.m; ++t) {
    double d2 = 0.0;
    for (std::size_t j = 0; j < s.dim; ++j) {
      const double diff = s.coords[j][t] - c[j];
      d2 += no_contract(diff * diff);
    }
    const double lo = cc2 > s.core2[t] ? cc2 : s.core2[t];
    const double m2 = d2 > lo ? d2 : lo;
    const bool better = m2 < s.key2[t];
    s.key2[t] = better ? m2 : s.key2[t];
    s.from[t] = better ? cur : s.from[t];
    if (s.key2[t] < best) {
      best = s.key2[t];
      best_t = t;
    }
  }
  return best_t;
}

#if defined(__SSE2__)
inline std::size_t prim_step_3d_sse2(PrimSoA& s, const double* c, double cc2, double cur) {
  const double* x = s.coords[0];
  const double* y = s.coords[1];
  const double* z = s.coords[2];
  double* key = s.key2;
  double* from = s.from;
  const double* core2 = s.core2;
  const __m128d cx = _mm_set1_pd(c[0]), cy = _mm_set1_pd(c[1]), cz = _mm_set1_pd(c[2]);
  const __m128d vcc = _mm_set1_pd(cc2), vcur = _mm_set1_pd(cur);
  __m128d vbest = _mm_set1_pd(std::numeric_limits<double>::infinity());
  __m128d vbest_t = _mm_set1_pd(-1.0);
  __m128d vt = _mm_set_pd(1.0, 0.0);
  const __m128d two = _mm_set1_pd(2.0);
  std::size_t t = 0;
  for (; t + 2 <= s.m; t += 2) {
    const __m128d dx = _mm_sub_pd(_mm_loadu_pd(x + t), cx);
    const __m128d dy = _mm_sub_pd(_mm_loadu_pd(y + t), cy);
    const __m128d dz = _mm_sub_pd(_mm_loadu_pd(z + t), cz);
    __m128d d2 = no_contract_simd(_mm_mul_pd(dx, dx));
    d2 = _mm_add_pd(d2, no_contract_simd(_mm_mul_pd(dy, dy)));
    d2 = _mm_add_pd(d2, no_contract_simd(_mm_mul_pd(dz, dz)));
    const __m128d lo = _mm_max_pd(_mm_loadu_pd(core2 + t), vcc);
    const __m128d m2 = _mm_max_pd(lo, d2);
    const __m128d k = _mm_loadu_pd(key + t);
    const __m128d better = _mm_cmplt_pd(m2, k);
    const __m128d nk = _mm_or_pd(_mm_and_pd(better, m2), _mm_andnot_pd(better, k));
    _mm_storeu_pd(key + t, nk);
    const __m128d f = _mm_loadu_pd(from + t);
    _mm_storeu_pd(from + t, _mm_or_pd(_mm_and_pd(better, vcur), _mm_andnot_pd(better, f)));
    const __m128d lt = _mm_cmplt_pd(nk, vbest);  // strict: keeps the first index per lane
    vbest = _mm_or_pd(_mm_and_pd(lt, nk), _mm_andnot_pd(lt, vbest));
    vbest_t = _mm_or_pd(_mm_and_pd(lt, vt), _mm_andnot_pd(lt, vbest_t));
    vt = _mm_add_pd(vt, two);
  }
  alignas(16) double bv[2], bt[2];
  _mm_store_pd(bv, vbest);
  _mm_store_pd(bt, vbest_t);
  double best = bv[0];
  double best_t = bt[0];
  if (bv[1] < best || (bv[1] == best && bt[1] >= 0.0 && (best_t < 0.0 || bt[1] < best_t))) {
    best = bv[1];
    best_t = bt[1];
  }
  for (; t < s.m; ++t) {  // tail
    double d2 = 0.0;
    for (std::size_t j = 0; j < 3; ++j) {
      const double diff = s.coords[j][t] - c[j];
      d2 += no_contract(diff * diff);
    }
    const double lo = cc2 > core2[t] ? cc2 : core2[t];
    const double m2 = d2 > lo ? d2 : lo;
    if (m2 < key[t]) {
      key[t] = m2;
      from[t] = cur;
    }
    if (key[t] < best) {
      best = key[t];
      best_t = static_cast<double>(t);
    }
  }
  return best_t < 0.0 ? s.m : static_cast<std::size_t>(best_t);
}
#endif

#if defined(__x86_64__) && defined(__GNUC__)
#define DS3D_HDBSCAN_AVX2 1
// no_contract() for functions with a target attribute: target("avx512f") enables FMA inside the
// function although the translation unit's __FMA__ is off, so the barrier must be unconditional.
inline double no_contract_x86(double p) {
  asm("" : "+v"(p));
  return p;
}

// The same step with 4-wide AVX2, compiled for that target only and chosen at run time (no FMA
// is enabled for this function, so products and sums stay separate roundings).
__attribute__((target("avx2"))) inline std::size_t prim_step_3d_avx2(PrimSoA& s, const double* c,
                                                                     double cc2, double cur) {
  const double* x = s.coords[0];
  const double* y = s.coords[1];
  const double* z = s.coords[2];
  double* key = s.key2;
  double* from = s.from;
  const double* core2 = s.core2;
  const __m256d cx = _mm256_set1_pd(c[0]), cy = _mm256_set1_pd(c[1]), cz = _mm256_set1_pd(c[2]);
  const __m256d vcc = _mm256_set1_pd(cc2), vcur = _mm256_set1_pd(cur);
  __m256d vbest = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  __m256d vbest_t = _mm256_set1_pd(-1.0);
  __m256d vt = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
  const __m256d four = _mm256_set1_pd(4.0);
  std::size_t t = 0;
  for (; t + 4 <= s.m; t += 4) {
    const __m256d dx = _mm256_sub_pd(_mm256_loadu_pd(x + t), cx);
    const __m256d dy = _mm256_sub_pd(_mm256_loadu_pd(y + t), cy);
    const __m256d dz = _mm256_sub_pd(_mm256_loadu_pd(z + t), cz);
    __m256d d2 = _mm256_mul_pd(dx, dx);
    d2 = _mm256_add_pd(d2, _mm256_mul_pd(dy, dy));
    d2 = _mm256_add_pd(d2, _mm256_mul_pd(dz, dz));
    const __m256d lo = _mm256_max_pd(_mm256_loadu_pd(core2 + t), vcc);
    const __m256d m2 = _mm256_max_pd(lo, d2);
    const __m256d k = _mm256_loadu_pd(key + t);
    const __m256d better = _mm256_cmp_pd(m2, k, _CMP_LT_OQ);
    const __m256d nk = _mm256_blendv_pd(k, m2, better);
    _mm256_storeu_pd(key + t, nk);
    _mm256_storeu_pd(from + t, _mm256_blendv_pd(_mm256_loadu_pd(from + t), vcur, better));
    const __m256d lt = _mm256_cmp_pd(nk, vbest, _CMP_LT_OQ);  // strict: first index per lane
    vbest = _mm256_blendv_pd(vbest, nk, lt);
    vbest_t = _mm256_blendv_pd(vbest_t, vt, lt);
    vt = _mm256_add_pd(vt, four);
  }
  alignas(32) double bv[4], bt[4];
  _mm256_store_pd(bv, vbest);
  _mm256_store_pd(bt, vbest_t);
  double best = std::numeric_limits<double>::infinity();
  double best_t = -1.0;
  for (int l = 0; l < 4; ++l) {
    if (bt[l] < 0.0) continue;
    if (bv[l] < best || (bv[l] == best && bt[l] < best_t)) {
      best = bv[l];
      best_t = bt[l];
    }
  }
  for (; t < s.m; ++t) {  // tail
    double d2 = 0.0;
    for (std::size_t j = 0; j < 3; ++j) {
      const double diff = s.coords[j][t] - c[j];
      d2 += no_contract_x86(diff * diff);
    }
    const double lo = cc2 > core2[t] ? cc2 : core2[t];
    const double m2 = d2 > lo ? d2 : lo;
    if (m2 < key[t]) {
      key[t] = m2;
      from[t] = cur;
    }
    if (key[t] < best) {
      best = key[t];
      best_t = static_cast<double>(t);
    }
  }
  return best_t < 0.0 ? s.m : static_cast<std::size_t>(best_t);
}

#define DS3D_HDBSCAN_AVX512 1
// GCC 12's _mm512_max_pd uses _mm512_undefined_pd, which trips a false
// -Wmaybe-uninitialized under -Werror.
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
inline __attribute__((target("avx512f"))) __m512d no_contract_v512(__m512d v) {
  asm("" : "+v"(v));  // no FMA contraction across this product, whatever -ffp-contract says
  return v;
}

// The same step, 8 lanes wide with AVX-512F (run-time dispatch; valgrind does not emulate it, so
// callgrind counts show the AVX2 step). Lanes track only the smallest key; its first slot is
// then found by a second, early-exit pass, so the tie rule (first index) is unchanged.
__attribute__((target("avx512f"))) inline std::size_t prim_step_3d_avx512(PrimSoA& s,
                                                                          const double* c,
                                                                          double cc2, double cur) {
  const double* x = s.coords[0];
  const double* y = s.coords[1];
  const double* z = s.coords[2];
  double* key = s.key2;
  double* from = s.from;
  const double* core2 = s.core2;
  const __m512d cx = _mm512_set1_pd(c[0]), cy = _mm512_set1_pd(c[1]), cz = _mm512_set1_pd(c[2]);
  const __m512d vcc = _mm512_set1_pd(cc2), vcur = _mm512_set1_pd(cur);
  __m512d vbest = _mm512_set1_pd(std::numeric_limits<double>::infinity());
  std::size_t t = 0;
  for (; t + 8 <= s.m; t += 8) {
    const __m512d dx = _mm512_sub_pd(_mm512_loadu_pd(x + t), cx);
    const __m512d dy = _mm512_sub_pd(_mm512_loadu_pd(y + t), cy);
    const __m512d dz = _mm512_sub_pd(_mm512_loadu_pd(z + t), cz);
    __m512d d2 = no_contract_v512(_mm512_mul_pd(dx, dx));
    d2 = _mm512_add_pd(d2, no_contract_v512(_mm512_mul_pd(dy, dy)));
    d2 = _mm512_add_pd(d2, no_contract_v512(_mm512_mul_pd(dz, dz)));
    const __m512d m2 = _mm512_max_pd(_mm512_max_pd(_mm512_loadu_pd(core2 + t), vcc), d2);
    const __m512d k = _mm512_loadu_pd(key + t);
    const __mmask8 better = _mm512_cmp_pd_mask(m2, k, _CMP_LT_OQ);
    _mm512_mask_storeu_pd(key + t, better, m2);
    _mm512_mask_storeu_pd(from + t, better, vcur);
    vbest = _mm512_min_pd(vbest, _mm512_mask_blend_pd(better, k, m2));
  }
  alignas(64) double lanes[8];
  _mm512_store_pd(lanes, vbest);
  double best = lanes[0];
  for (int l = 1; l < 8; ++l) best = lanes[l] < best ? lanes[l] : best;
  const std::size_t vec_end = t;
  for (; t < s.m; ++t) {  // tail
    double d2 = 0.0;
    for (std::size_t j = 0; j < 3; ++j) {
      const double diff = s.coords[j][t] - c[j];
      d2 += no_contract_x86(diff * diff);
    }
    const double lo = cc2 > core2[t] ? cc2 : core2[t];
    const double m2 = d2 > lo ? d2 : lo;
    if (m2 < key[t]) {
      key[t] = m2;
      from[t] = cur;
    }
    if (key[t] < best) best = key[t];
  }
  if (!(best < std::numeric_limits<double>::infinity())) return s.m;
  const __m512d vb = _mm512_set1_pd(best);
  for (std::size_t u = 0; u < vec_end; u += 8) {  // first slot holding the smallest key
    const auto hit =
        static_cast<unsigned>(_mm512_cmp_pd_mask(_mm512_loadu_pd(key + u), vb, _CMP_EQ_OQ));
    if (hit != 0U) return u + static_cast<std::size_t>(__builtin_ctz(hit));
  }
  for (std::size_t u = vec_end; u < s.m; ++u) {
    if (key[u] == best) return u;
  }
  return s.m;
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif

inline bool cpu_has_avx512() {
  static const bool has = __builtin_cpu_supports("avx512f") != 0;
  return has;
}

inline bool cpu_has_avx2() {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}
#endif

// Queries per BoruvkaKdTree core-distance walk (SIMD lanes) for dimension dim, list length kk =
// k + 1 and mode `lanes`: 8 (AVX-512F), 4 (AVX2) or 0 (one walk per query).
inline std::size_t knn_lane_width(std::size_t dim, std::size_t kk, KnnLanes lanes) {
  if (dim != 3 || kk > 16 || lanes == KnnLanes::kPerQuery) return 0;
  bool avx2 = false;
  bool avx512 = false;
#if defined(__AVX2__)
  avx2 = true;
#endif
#if defined(DS3D_HDBSCAN_AVX512)
  avx512 = cpu_has_avx512();
#endif
  if (lanes == KnnLanes::kAvx2 && avx2) return 4;
  if (avx512) return 8;
  return avx2 ? 4 : 0;
}

inline bool prim_step_available(PrimStep step, std::size_t dim) {
  switch (step) {
    case PrimStep::kGeneric:
      return true;
    case PrimStep::kSse2:
#if defined(__SSE2__)
      return dim == 3;
#else
      return false;
#endif
    case PrimStep::kAvx2:
#if defined(DS3D_HDBSCAN_AVX2)
      return dim == 3 && cpu_has_avx2();
#else
      return false;
#endif
    case PrimStep::kAvx512:
#if defined(DS3D_HDBSCAN_AVX512)
      return dim == 3 && cpu_has_avx512();
#else
      return false;
#endif
    default:
      return false;
  }
}

inline std::vector<MstEdge> prim_dense(const double* data, std::size_t n, std::size_t dim,
                                       const std::vector<double>& core,
                                       PrimStep step = PrimStep::kAuto) {
  std::vector<MstEdge> edges;
  if (n < 2) return edges;
  edges.reserve(n - 1);
  const double inf = std::numeric_limits<double>::infinity();
  // Slot counts are kept a multiple of kPrimPad: the slots past the points are retired dummies
  // (key and core +inf: never updated, never picked, dropped by compaction), so the SIMD steps
  // run without a scalar tail.
  const auto padded = [](std::size_t m) { return (m + kPrimPad - 1) / kPrimPad * kPrimPad; };
  PrimSoA s;
  s.dim = dim;
  s.m = padded(n - 1);
  s.allocate(s.m);
  std::fill_n(s.core2, s.m, inf);
  std::fill_n(s.key2, s.m, inf);
  for (std::size_t t = 0; t + 1 < n; ++t) {
    s.idx[t] = static_cast<std::uint32_t>(t + 1);
    s.core2[t] = core[t + 1] * core[t + 1];
    for (std::size_t j = 0; j < dim; ++j) s.coords[j][t] = data[(t + 1) * dim + j];
  }
  if (dim != 3) step = PrimStep::kGeneric;
  if (step == PrimStep::kAuto || !prim_step_available(step, dim)) {
    step = prim_step_available(PrimStep::kAvx512, dim) ? PrimStep::kAvx512
           : prim_step_available(PrimStep::kAvx2, dim) ? PrimStep::kAvx2
           : prim_step_available(PrimStep::kSse2, dim) ? PrimStep::kSse2
                                                       : PrimStep::kGeneric;
  }
  // Settled points: a key equal to the point's own squared core distance can never drop again
  // (every candidate max{κ_a², κ_b², d²} is >= κ_b²), so such a point leaves the streaming
  // arrays at the next compaction and waits in a min-heap ordered by (key, point id), the same
  // order as the step's first-minimum rule over slots in index order.
  struct Settled {
    double key2;
    std::uint32_t idx;
    std::uint32_t from;
  };
  const auto heap_after = [](const Settled& a, const Settled& b) {
    return a.key2 > b.key2 || (a.key2 == b.key2 && a.idx > b.idx);
  };
  std::vector<Settled> settled;
  std::size_t alive = n - 1;  // slots not yet retired (settled ones count until they move)
  std::size_t remaining = n - 1;
  std::uint32_t cur = 0;
  while (remaining > 0) {
    const double* c = data + static_cast<std::size_t>(cur) * dim;
    const double cc2 = core[cur] * core[cur];
    std::size_t best = s.m;
    if (alive > 0) {
      switch (step) {
#if defined(DS3D_HDBSCAN_AVX2)
        case PrimStep::kAvx512:
          best = prim_step_3d_avx512(s, c, cc2, static_cast<double>(cur));
          break;
        case PrimStep::kAvx2:
          best = prim_step_3d_avx2(s, c, cc2, static_cast<double>(cur));
          break;
#endif
#if defined(__SSE2__)
        case PrimStep::kSse2:
          best = prim_step_3d_sse2(s, c, cc2, static_cast<double>(cur));
          break;
#endif
        default:
          best = prim_step_generic(s, c, cc2, static_cast<double>(cur));
          break;
      }
      if (best == s.m && settled.empty()) {  // unreachable for finite input; stay connected
        for (std::size_t t = 0; t < s.m; ++t) {
          if (s.core2[t] != inf) best = t;
        }
      }
    }
    const bool take_settled =
        !settled.empty() &&
        (best == s.m || settled.front().key2 < s.key2[best] ||
         (settled.front().key2 == s.key2[best] && settled.front().idx < s.idx[best]));
    std::uint32_t to = 0;
    std::uint32_t src = 0;
    if (take_settled) {
      to = settled.front().idx;
      src = settled.front().from;
      std::pop_heap(settled.begin(), settled.end(), heap_after);
      settled.pop_back();
    } else {
      to = s.idx[best];
      src = static_cast<std::uint32_t>(s.from[best]);
      s.key2[best] = inf;
      s.core2[best] = inf;
      --alive;
    }
    const double d = std::sqrt(sq_dist_seq(data + static_cast<std::size_t>(src) * dim,
                                           data + static_cast<std::size_t>(to) * dim, dim));
    edges.push_back({src, to, std::max({core[src], core[to], d})});
    cur = to;
    --remaining;
    if (alive > 0 && 8 * alive < 7 * s.m) {  // order-preserving compaction, 1/8 retired
      std::size_t w = 0;
      for (std::size_t t = 0; t < s.m; ++t) {
        if (s.core2[t] == inf) continue;
        if (s.key2[t] == s.core2[t]) {  // settled: key final
          settled.push_back({s.key2[t], s.idx[t], static_cast<std::uint32_t>(s.from[t])});
          std::push_heap(settled.begin(), settled.end(), heap_after);
          continue;
        }
        s.idx[w] = s.idx[t];
        s.core2[w] = s.core2[t];
        s.key2[w] = s.key2[t];
        s.from[w] = s.from[t];
        for (std::size_t j = 0; j < dim; ++j) s.coords[j][w] = s.coords[j][t];
        ++w;
      }
      alive = w;
      for (; w < padded(alive); ++w) {  // retired dummies up to the padded count
        s.core2[w] = inf;
        s.key2[w] = inf;
        for (std::size_t j = 0; j < dim; ++j) s.coords[j][w] = 0.0;
      }
      s.m = w;
    }
  }
  return edges;
}

// Prim on a precomputed dense distance matrix (row-major n × n). O(n²) time, O(n) memory.
inline std::vector<MstEdge> prim_precomputed(const double* dist, std::size_t n,
                                             const std::vector<double>& core) {
  std::vector<MstEdge> edges;
  if (n < 2) return edges;
  edges.reserve(n - 1);
  std::vector<double> key(n, std::numeric_limits<double>::infinity());
  std::vector<std::uint32_t> from(n, 0);
  std::vector<std::uint32_t> rem(n - 1);
  for (std::size_t t = 0; t + 1 < n; ++t) rem[t] = static_cast<std::uint32_t>(t + 1);
  std::uint32_t cur = 0;
  while (!rem.empty()) {
    const double* row = dist + static_cast<std::size_t>(cur) * n;
    std::size_t best = 0;
    double best_key = std::numeric_limits<double>::infinity();
    for (std::size_t t = 0; t < rem.size(); ++t) {
      const std::uint32_t j = rem[t];
      const double mr = std::max({core[cur], core[j], row[j]});
      if (mr < key[j]) {
        key[j] = mr;
        from[j] = cur;
      }
      if (key[j] < best_key || t == 0) {
        best_key = key[j];
        best = t;
      }
    }
    const std::uint32_t nxt = rem[best];
    edges.push_back({from[nxt], nxt, key[nxt]});
    rem[best] = rem.back();
    rem.pop_back();
    cur = nxt;
  }
  return edges;
}

// KD-tree Borůvka on the mutual-reachability graph (McInnes & Healy 2017, "Accelerated
// Hierarchical Density Based Clustering", §3, single-tree variant). Each round every point keeps
// a candidate edge to another component: seeded from its k nearest neighbours (whose mutual
// reachability is max{κ(q), κ(p)}; when that equals κ(q) it is provably the cheapest edge of q),
// kept while its target stays in another component, and otherwise searched in a KD-tree that
// skips nodes lying entirely in q's component or whose lower bound max{κ(q), min κ in node, box
// distance} cannot beat the best known edge of q's component. The component bounds are computed
// before the (parallel) searches and only strictly better edges are accepted, so every point's
// result, and the MST, is independent of the thread count. Cycles among equal-weight picks are
// dropped by union-find, which keeps the forest minimal. O(n (D + k)) memory; O(log n) rounds.
class BoruvkaKdTree {
 public:
  /// Builds the tree over `data` (n × dim, row-major), computes every point's core distance
  /// (distance to its k-th nearest other point, 1 <= k < n) and seeds the candidate edges.
  /// With seeds = false only the core distances are computed (no candidate edges: run() must
  /// not be called).
  BoruvkaKdTree(const double* data, std::size_t n, std::size_t dim, std::size_t k, int num_threads,
                KnnLanes lanes = KnnLanes::kAuto, bool seeds = true)
      : n_(n), dim_(dim), threads_(num_threads), lanes_(lanes), seeds_(seeds) {
    perm_.resize(n);
    std::iota(perm_.begin(), perm_.end(), 0U);
    pts_.resize(n * dim);
    core_.resize(n);
    build(data);
    knn_and_seeds(k + 1);
    lower_ = core_;
  }

  /// Core distances by point id.
  [[nodiscard]] std::vector<double> core_distances() const {
    std::vector<double> c(n_);
    for (std::size_t i = 0; i < n_; ++i) c[perm_[i]] = core_[i];
    return c;
  }

  std::vector<MstEdge> run() {
    std::vector<MstEdge> edges;
    edges.reserve(n_ - 1);
    uf_parent_.resize(n_);
    std::iota(uf_parent_.begin(), uf_parent_.end(), 0U);
    // Components are numbered 0..nc-1 in the order of their root point ids, so the per-component
    // passes below cost O(nc), not O(n), and edges are emitted in root order as before.
    std::vector<std::uint32_t> comp(n_);   // component of each tree position
    std::vector<std::uint32_t> dense(n_);  // root point id -> component
    std::vector<double> comp_w(n_);
    std::vector<std::uint32_t> comp_q(n_);
    std::vector<std::uint32_t> comp_start(n_ + 1), fill(n_), members(n_);
    const double inf = std::numeric_limits<double>::infinity();
    while (edges.size() + 1 < n_) {
      std::uint32_t nc = 0;
      for (std::uint32_t x = 0; x < n_; ++x) {
        if (uf_parent_[x] == x) dense[x] = nc++;
      }
      for (std::size_t i = 0; i < n_; ++i) comp[i] = dense[find(perm_[i])];
      label_nodes(comp);
      // Drop candidates that now point into the own component; component bounds from the rest.
      std::fill(comp_w.begin(), comp_w.begin() + nc, inf);
      for (std::size_t i = 0; i < n_; ++i) {
        if (cand_w_[i] < inf && comp[cand_t_[i]] == comp[i]) cand_w_[i] = inf;
        if (cand_w_[i] < comp_w[comp[i]]) {
          comp_w[comp[i]] = cand_w_[i];
          comp_q[comp[i]] = static_cast<std::uint32_t>(i);
        }
      }
      comp_ = comp.data();
      // Members of each component, contiguous and in tree order (counting sort). Each
      // component is searched by one thread in this fixed order, so its running bound, and
      // hence every result, is the same for any thread count.
      std::fill(comp_start.begin(), comp_start.begin() + nc + 1, 0U);
      for (std::size_t i = 0; i < n_; ++i) ++comp_start[comp[i] + 1];
      for (std::size_t c = 0; c < nc; ++c) comp_start[c + 1] += comp_start[c];
      std::copy(comp_start.begin(), comp_start.begin() + nc, fill.begin());
      for (std::size_t i = 0; i < n_; ++i) members[fill[comp[i]]++] = static_cast<std::uint32_t>(i);
      parallel_chunks(nc, std::size_t{64} * static_cast<std::size_t>(std::max(1, threads_)),
                      threads_, [&](std::size_t b, std::size_t e, std::size_t) {
                        for (std::size_t r = b; r < e; ++r) {
                          const auto c = static_cast<std::uint32_t>(r);
                          double bound = comp_w[c];
                          for (auto m = comp_start[c]; m < comp_start[c + 1];) {
                            const std::int32_t k = pure_start_[members[m]];
                            if (k >= 0) {
                              process_node(static_cast<std::size_t>(k), c, bound);
                              m += nodes_[static_cast<std::size_t>(k)].end -
                                   nodes_[static_cast<std::size_t>(k)].begin;
                            } else {
                              query(members[m], bound);
                              ++m;
                            }
                          }
                        }
                      });
      // Deterministic reduction: smallest weight, then smallest tree position.
      for (std::size_t i = 0; i < n_; ++i) {
        const auto c = comp[i];
        if (cand_w_[i] < comp_w[c] ||
            (cand_w_[i] == comp_w[c] && cand_w_[i] < inf && i < comp_q[c])) {
          comp_w[c] = cand_w_[i];
          comp_q[c] = static_cast<std::uint32_t>(i);
        }
      }
      std::size_t added = 0;
      for (std::size_t c = 0; c < nc; ++c) {
        if (comp_w[c] == inf) continue;
        const std::uint32_t qi = comp_q[c];
        const std::uint32_t a = perm_[qi];
        const std::uint32_t b = perm_[cand_t_[qi]];
        const auto ra = find(a);
        const auto rb = find(b);
        if (ra == rb) continue;
        uf_parent_[ra] = rb;
        edges.push_back({a, b, comp_w[c]});
        ++added;
      }
      if (added == 0) break;  // cannot happen for a complete graph; guards against bad input
    }
    return edges;
  }

 private:
  struct Node {
    std::uint32_t begin, end;
    std::int32_t left, right;  // -1 for leaves
    double min_core;
    std::uint32_t comp;   // component of all points, or kMixed
    std::int32_t parent;  // -1 for the root
  };
  static constexpr std::uint32_t kMixed = 0xFFFFFFFFU;
  static constexpr std::uint32_t kLeafSize = 16;
  static constexpr std::uint32_t kKeyedMax = 65536;  // largest node built on keyed_

  std::uint32_t find(std::uint32_t x) {
    std::uint32_t r = x;
    while (uf_parent_[r] != r) r = uf_parent_[r];
    while (uf_parent_[x] != r) {
      const auto nx = uf_parent_[x];
      uf_parent_[x] = r;
      x = nx;
    }
    return r;
  }

  void build(const double* data) {
    nodes_.reserve(2 * (n_ / kLeafSize + 1));
    std::vector<std::uint32_t> order(n_);
    std::iota(order.begin(), order.end(), 0U);
    keyed_.resize(std::min<std::size_t>(n_, kKeyedMax));
    build_node(data, order, 0, static_cast<std::uint32_t>(n_));
    keyed_ = {};
    stride_ = n_ + kLeafSize;  // zero padding: a block read of kLeafSize lanes never overruns
    soa_.assign(stride_ * dim_, 0.0);
    for (std::size_t i = 0; i < n_; ++i) {
      perm_[i] = order[i];
      for (std::size_t j = 0; j < dim_; ++j) {
        pts_[i * dim_ + j] = data[order[i] * dim_ + j];
        soa_[j * stride_ + i] = pts_[i * dim_ + j];
      }
    }
    for (std::size_t k = 0; k < nodes_.size(); ++k) {
      if (nodes_[k].left < 0) leaves_.push_back(static_cast<std::uint32_t>(k));
    }
  }

  // Squared distances from q to the kLeafSize tree positions from b into buf (lanes past a
  // node's end read other points or the zero padding; callers mask them), each summed in
  // dimension order with separate roundings, i.e. bitwise sq_dist_seq. Returns the bit mask of
  // the lanes with buf[t] < r2 (kLe = false) or buf[t] <= r2 (kLe = true).
  template <bool kLe>
  std::uint32_t block_dist2(const double* q, std::size_t b, double r2, double* buf) const {
#if defined(__AVX2__)
    if (dim_ == 3) {
      const double* xs = soa_.data() + b;
      const double* ys = xs + stride_;
      const double* zs = ys + stride_;
      const __m256d qx = _mm256_set1_pd(q[0]);
      const __m256d qy = _mm256_set1_pd(q[1]);
      const __m256d qz = _mm256_set1_pd(q[2]);
      const __m256d w = _mm256_set1_pd(r2);
      std::uint32_t bits = 0;
      for (std::uint32_t v = 0; v < kLeafSize; v += 4) {
        const __m256d dx = _mm256_sub_pd(_mm256_loadu_pd(xs + v), qx);
        const __m256d dy = _mm256_sub_pd(_mm256_loadu_pd(ys + v), qy);
        const __m256d dz = _mm256_sub_pd(_mm256_loadu_pd(zs + v), qz);
        __m256d d2 = no_contract_simd(_mm256_mul_pd(dx, dx));
        d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dy, dy)));
        d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dz, dz)));
        _mm256_storeu_pd(buf + v, d2);
        const __m256d hit =
            kLe ? _mm256_cmp_pd(d2, w, _CMP_LE_OQ) : _mm256_cmp_pd(d2, w, _CMP_LT_OQ);
        bits |= static_cast<std::uint32_t>(_mm256_movemask_pd(hit)) << v;
      }
      return bits;
    }
#endif
    {
      const double* x = soa_.data() + b;
      const double q0 = q[0];
      for (std::uint32_t t = 0; t < kLeafSize; ++t) {
        const double g = x[t] - q0;
        buf[t] = no_contract(g * g);
      }
    }
    for (std::size_t j = 1; j < dim_; ++j) {
      const double* x = soa_.data() + j * stride_ + b;
      const double qj = q[j];
      for (std::uint32_t t = 0; t < kLeafSize; ++t) {
        const double g = x[t] - qj;
        buf[t] += no_contract(g * g);
      }
    }
    std::uint32_t bits = 0;
    for (std::uint32_t t = 0; t < kLeafSize; ++t) {
      bits |= static_cast<std::uint32_t>(kLe ? buf[t] <= r2 : buf[t] < r2) << t;
    }
    return bits;
  }

  // Offers the points of node nd to the ascending list bd of the kk smallest squared distances
  // from q (+inf while not full; worst = bd[kk - 1]). Each hit below worst is merged by
  // bd[i] = min(bd[i], max(bd[i-1], x)), a branch-free sorted insertion.
  void knn_scan(const double* q, const Node& nd, std::size_t kk, double* bd, double& worst) const {
#if defined(__AVX2__)
    if (dim_ == 3) {
      if (kk <= 4) return knn_scan_avx2<1>(q, nd, kk, bd, worst);
      if (kk <= 8) return knn_scan_avx2<2>(q, nd, kk, bd, worst);
      if (kk <= 12) return knn_scan_avx2<3>(q, nd, kk, bd, worst);
      if (kk <= 16) return knn_scan_avx2<4>(q, nd, kk, bd, worst);
    }
#endif
    double buf[kLeafSize];
    for (std::size_t b = nd.begin; b < nd.end; b += kLeafSize) {
      const auto len = static_cast<std::uint32_t>(std::min<std::size_t>(kLeafSize, nd.end - b));
      std::uint32_t bits = block_dist2<false>(q, b, worst, buf) & ((1U << len) - 1U);
      while (bits != 0U) {
        const auto t = static_cast<std::uint32_t>(std::countr_zero(bits));
        bits &= bits - 1U;
        const double x = buf[t];
        if (!(x < worst)) continue;  // cannot lower the kk-th smallest
        for (std::size_t i = kk - 1; i > 0; --i) bd[i] = std::min(bd[i], std::max(bd[i - 1], x));
        bd[0] = std::min(bd[0], x);
        worst = bd[kk - 1];
      }
    }
  }

  // Leaf-first walk for the queries of knn_and_seeds: node `leaf` (holding q) first, then for
  // each ancestor the other child's subtree, nearest child first inside it. Every subtree whose
  // box is not accepted by keep(box²) is skipped; visit(node) handles the leaves met.
  template <class Keep, class Visit>
  void walk_from_leaf(const double* q, std::uint32_t leaf, Keep&& keep, Visit&& visit) const {
    visit(nodes_[leaf]);
    struct Entry {
      std::uint32_t node;
      double box2;
    };
    Entry stack[128];
    for (std::uint32_t c = leaf; nodes_[c].parent >= 0;) {
      const auto p = static_cast<std::uint32_t>(nodes_[c].parent);
      const Node& pn = nodes_[p];
      const auto sib =
          static_cast<std::uint32_t>(pn.left == static_cast<std::int32_t>(c) ? pn.right : pn.left);
      c = p;
      int top = 0;
      stack[top++] = {sib, box_dist2(q, sib)};
      while (top > 0) {
        const Entry en = stack[--top];
        if (!keep(en.box2)) continue;
        const Node& nd = nodes_[en.node];
        if (nd.left < 0) {
          visit(nd);
          continue;
        }
        const auto l = static_cast<std::uint32_t>(nd.left);
        const auto r = static_cast<std::uint32_t>(nd.right);
        const Entry el{l, box_dist2(q, l)};
        const Entry er{r, box_dist2(q, r)};
        if (el.box2 <= er.box2) {  // nearer child on top
          if (keep(er.box2)) stack[top++] = er;
          if (keep(el.box2)) stack[top++] = el;
        } else {
          if (keep(el.box2)) stack[top++] = el;
          if (keep(er.box2)) stack[top++] = er;
        }
      }
    }
  }

  // Pass 1 of knn_and_seeds for tree position s (in leaf `leaf`): bd receives the kk smallest
  // squared distances from s, ascending. Every leaf it scans is appended to `seen` once (mark
  // holds the stamp of the leaf batch that listed it). Boxes are kept while box² <= the current
  // kk-th value (not <), so the scanned leaves cover the whole core ball, boundary ties included.
  void knn_query(std::uint32_t s, std::uint32_t leaf, std::size_t kk, double* bd,
                 std::vector<std::uint32_t>& seen, std::vector<std::uint32_t>& mark,
                 std::uint32_t stamp) const {
    const double* q = pts_.data() + static_cast<std::size_t>(s) * dim_;
    std::fill(bd, bd + ((kk + 3) & ~std::size_t{3}), std::numeric_limits<double>::infinity());
    double worst = std::numeric_limits<double>::infinity();
    walk_from_leaf(
        q, leaf, [&](double box2) { return box2 <= worst; },
        [&](const Node& nd) {
          const auto id = static_cast<std::size_t>(&nd - nodes_.data());
          if (mark[id] != stamp) {
            mark[id] = stamp;
            seen.push_back(static_cast<std::uint32_t>(id));
          }
          knn_scan(q, nd, kk, bd, worst);
        });
  }

  // Pass 2 of knn_and_seeds: the cheapest (weight, tree position) edge from s to its core ball
  // (squared radius rs), looked up in `near`, the leaves that pass 1 scanned for s's leaf, in
  // tree order.
  void seed_query(std::uint32_t s, const std::uint32_t* near, std::size_t num_near, double rs,
                  double& best_w, std::uint32_t& best_t) const {
    const double* q = pts_.data() + static_cast<std::size_t>(s) * dim_;
    const double cs = core_[s];
    double buf[kLeafSize];
    for (std::size_t u = 0; u < num_near; ++u) {
      const Node& nd = nodes_[near[u]];
      // `near` is in tree order and no edge of s weighs less than core(s): once that weight is
      // reached, later leaves can only tie it with larger tree positions.
      if (best_w == cs && nd.begin >= best_t) break;
      {
        // The leaf can only hold a better seed if max{core(s), its min core} is below best_w,
        // or equal to it with a smaller tree position.
        const double lb = std::max(cs, nd.min_core);
        if (!(lb < best_w || (lb == best_w && nd.begin < best_t))) continue;
        if (box_dist2(q, near[u]) > rs) continue;
        for (std::size_t bb = nd.begin; bb < nd.end; bb += kLeafSize) {
          const auto len =
              static_cast<std::uint32_t>(std::min<std::size_t>(kLeafSize, nd.end - bb));
          std::uint32_t bits = block_dist2<true>(q, bb, rs, buf) & ((1U << len) - 1U);
          while (bits != 0U) {
            const auto t =
                static_cast<std::uint32_t>(bb) + static_cast<std::uint32_t>(std::countr_zero(bits));
            bits &= bits - 1U;
            if (t == s) continue;
            const double w = std::max(cs, core_[t]);
            if (w < best_w || (w == best_w && t < best_t)) {
              best_w = w;
              best_t = t;
            }
          }
        }
      }
    }
  }

  // Smallest node holding tree positions p0 .. p0 + cnt - 1: descends from the root while one
  // child holds them all.
  [[nodiscard]] std::uint32_t group_start(std::uint32_t p0, std::uint32_t cnt) const {
    std::uint32_t start = 0;
    for (;;) {
      const Node& nd = nodes_[start];
      if (nd.left < 0) return start;
      const auto l = static_cast<std::uint32_t>(nd.left);
      const auto r = static_cast<std::uint32_t>(nd.right);
      if (p0 + cnt <= nodes_[l].end) {
        start = l;
      } else if (p0 >= nodes_[r].begin) {
        start = r;
      } else {
        return start;
      }
    }
  }

#if defined(__AVX2__)
  // knn_scan with the list held in kB 4-lane registers (4·kB >= kk slots, ascending; bd must
  // have 4·kB slots). The merge runs on whole registers: bd[i-1] is the list shifted up one lane
  // (a lane permute plus the top lane of the register below; -inf below slot 0). The same
  // values as the scalar merge (as KnnTreeSmall::scan_core_avx2).
  template <int kB>
  void knn_scan_avx2(const double* q, const Node& nd, std::size_t kk, double* bd,
                     double& worst) const {
    __m256d v[kB];
    for (int j = 0; j < kB; ++j) v[j] = _mm256_loadu_pd(bd + 4 * j);
    const int wl = static_cast<int>((kk - 1) & 3U);  // lane of slot kk - 1 in v[(kk - 1) / 4]
    const auto wb = static_cast<int>((kk - 1) / 4);
    const __m256d neg_inf = _mm256_set1_pd(-std::numeric_limits<double>::infinity());
    double buf[kLeafSize];
    for (std::size_t b = nd.begin; b < nd.end; b += kLeafSize) {
      const auto len = static_cast<std::uint32_t>(std::min<std::size_t>(kLeafSize, nd.end - b));
      std::uint32_t bits = block_dist2<false>(q, b, worst, buf) & ((1U << len) - 1U);
      while (bits != 0U) {
        const auto t = static_cast<std::uint32_t>(std::countr_zero(bits));
        bits &= bits - 1U;
        const double x = buf[t];
        if (!(x < worst)) continue;  // cannot lower the kk-th smallest
        const __m256d vx = _mm256_set1_pd(x);
        for (int j = kB - 1; j >= 0; --j) {
          const __m256d below = j > 0 ? _mm256_permute4x64_pd(v[j - 1], 0xFF) : neg_inf;
          const __m256d up = _mm256_blend_pd(_mm256_permute4x64_pd(v[j], 0x93), below, 0x1);
          v[j] = _mm256_min_pd(v[j], _mm256_max_pd(up, vx));
        }
        alignas(32) double top[4];
        _mm256_store_pd(top, v[wb]);
        worst = top[wl];
      }
    }
    for (int j = 0; j < kB; ++j) _mm256_storeu_pd(bd + 4 * j, v[j]);
  }

  // Pass 1 of knn_and_seeds for four queries at once, one per AVX2 lane: the tree positions
  // p0 .. p0 + cnt - 1 (cnt in 1..4; missing lanes repeat the last query). Each lane keeps its
  // list of the kk smallest squared distances in kL registers, slot i of every lane in v[i],
  // ascending, the first kL - kk slots held at -inf so that v[kL - 1] is the kk-th smallest.
  // Every point of a scanned leaf is merged into all four lists, branch-free, by
  // v[i] = min(v[i], max(v[i-1], d)) (no per-hit bit extraction or serial dependency between
  // the queries). The walk starts at the smallest node holding the four positions (its whole
  // subtree: their own points), then visits each ancestor's other subtree, nearest child first;
  // a node is skipped when its box is beyond the current kk-th value in every lane (box² > v,
  // so the scanned leaves cover every lane's core ball, boundary ties included). Per lane the
  // distances and box gaps are those of sq_dist_seq and box_dist2 (same operations, same
  // order), so each lane's kk-th value is bitwise brute force. The scanned leaves are appended
  // to `seen`; out_r2[l] receives lane l's kk-th smallest squared distance.
  template <int kL>
  void knn_group_avx2(std::uint32_t p0, std::uint32_t cnt, std::size_t kk, double* out_r2,
                      std::vector<std::uint32_t>& seen) const {
    const double inf = std::numeric_limits<double>::infinity();
    alignas(32) double qc[3][4];
    for (std::uint32_t l = 0; l < 4; ++l) {
      const double* p = pts_.data() + static_cast<std::size_t>(p0 + std::min(l, cnt - 1)) * 3;
      for (int j = 0; j < 3; ++j) qc[j][l] = p[j];
    }
    const __m256d qx = _mm256_load_pd(qc[0]);
    const __m256d qy = _mm256_load_pd(qc[1]);
    const __m256d qz = _mm256_load_pd(qc[2]);
    __m256d v[kL];
    for (int i = 0; i < kL; ++i) {
      v[i] = _mm256_set1_pd(static_cast<std::size_t>(i) < kL - kk ? -inf : inf);
    }
    const __m256d zero = _mm256_setzero_pd();
    auto box2 = [&](std::size_t k) {
      const double* lo = lo_.data() + k * 3;
      const double* hi = hi_.data() + k * 3;
      const __m256d gx = _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo), qx),
                                                     _mm256_sub_pd(qx, _mm256_broadcast_sd(hi))),
                                       zero);
      const __m256d gy =
          _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo + 1), qy),
                                      _mm256_sub_pd(qy, _mm256_broadcast_sd(hi + 1))),
                        zero);
      const __m256d gz =
          _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo + 2), qz),
                                      _mm256_sub_pd(qz, _mm256_broadcast_sd(hi + 2))),
                        zero);
      __m256d s = no_contract_simd(_mm256_mul_pd(gx, gx));
      s = _mm256_add_pd(s, no_contract_simd(_mm256_mul_pd(gy, gy)));
      return _mm256_add_pd(s, no_contract_simd(_mm256_mul_pd(gz, gz)));
    };
    auto keep = [&](__m256d b2) {
      return _mm256_movemask_pd(_mm256_cmp_pd(b2, v[kL - 1], _CMP_LE_OQ)) != 0;
    };
    auto scan = [&](const Node& nd) {
      seen.push_back(static_cast<std::uint32_t>(&nd - nodes_.data()));
      const double* p = pts_.data() + static_cast<std::size_t>(nd.begin) * 3;
      for (auto t = nd.begin; t < nd.end; ++t, p += 3) {
        const __m256d dx = _mm256_sub_pd(_mm256_broadcast_sd(p), qx);
        const __m256d dy = _mm256_sub_pd(_mm256_broadcast_sd(p + 1), qy);
        const __m256d dz = _mm256_sub_pd(_mm256_broadcast_sd(p + 2), qz);
        __m256d d2 = no_contract_simd(_mm256_mul_pd(dx, dx));
        d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dy, dy)));
        d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dz, dz)));
#pragma GCC unroll 16
        for (int i = kL - 1; i > 0; --i) v[i] = _mm256_min_pd(v[i], _mm256_max_pd(v[i - 1], d2));
        v[0] = _mm256_min_pd(v[0], d2);
      }
    };
    struct alignas(32) Entry {
      __m256d box2;
      std::uint32_t node;
    };
    Entry stack[128];
    auto subtree = [&](std::uint32_t root, __m256d root_box2) {
      int top = 0;
      stack[top++] = {root_box2, root};
      while (top > 0) {
        const Entry en = stack[--top];
        if (!keep(en.box2)) continue;
        const Node& nd = nodes_[en.node];
        if (nd.left < 0) {
          scan(nd);
          continue;
        }
        const auto l = static_cast<std::uint32_t>(nd.left);
        const auto r = static_cast<std::uint32_t>(nd.right);
        const Entry el{box2(l), l};
        const Entry er{box2(r), r};
        // Nearer child (by lane 0) on top.
        if (_mm256_cvtsd_f64(el.box2) <= _mm256_cvtsd_f64(er.box2)) {
          if (keep(er.box2)) stack[top++] = er;
          if (keep(el.box2)) stack[top++] = el;
        } else {
          if (keep(el.box2)) stack[top++] = el;
          if (keep(er.box2)) stack[top++] = er;
        }
      }
    };
    const std::uint32_t start = group_start(p0, cnt);
    subtree(start, zero);
    for (std::uint32_t c = start; nodes_[c].parent >= 0;) {
      const auto p = static_cast<std::uint32_t>(nodes_[c].parent);
      const Node& pn = nodes_[p];
      const auto sib =
          static_cast<std::uint32_t>(pn.left == static_cast<std::int32_t>(c) ? pn.right : pn.left);
      c = p;
      subtree(sib, box2(sib));
    }
    alignas(32) double r[4];
    _mm256_store_pd(r, v[kL - 1]);
    for (std::uint32_t l = 0; l < cnt; ++l) out_r2[l] = r[l];
  }
#endif

#if defined(DS3D_HDBSCAN_AVX512)
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
  // knn_group_avx2 with eight queries, one per AVX-512 lane (the list in kL of the 32 zmm
  // registers). Run-time dispatch; written without lambdas, which would not inherit the target.
  [[nodiscard]] __attribute__((target("avx512f"))) __m512d box2_avx512(std::size_t k, __m512d qx,
                                                                       __m512d qy,
                                                                       __m512d qz) const {
    const double* lo = lo_.data() + k * 3;
    const double* hi = hi_.data() + k * 3;
    const __m512d zero = _mm512_setzero_pd();
    const __m512d gx = _mm512_max_pd(_mm512_max_pd(_mm512_sub_pd(_mm512_set1_pd(lo[0]), qx),
                                                   _mm512_sub_pd(qx, _mm512_set1_pd(hi[0]))),
                                     zero);
    const __m512d gy = _mm512_max_pd(_mm512_max_pd(_mm512_sub_pd(_mm512_set1_pd(lo[1]), qy),
                                                   _mm512_sub_pd(qy, _mm512_set1_pd(hi[1]))),
                                     zero);
    const __m512d gz = _mm512_max_pd(_mm512_max_pd(_mm512_sub_pd(_mm512_set1_pd(lo[2]), qz),
                                                   _mm512_sub_pd(qz, _mm512_set1_pd(hi[2]))),
                                     zero);
    __m512d s = no_contract_v512(_mm512_mul_pd(gx, gx));
    s = _mm512_add_pd(s, no_contract_v512(_mm512_mul_pd(gy, gy)));
    return _mm512_add_pd(s, no_contract_v512(_mm512_mul_pd(gz, gz)));
  }

  template <int kL>
  __attribute__((target("avx512f"))) void knn_group_avx512(std::uint32_t p0, std::uint32_t cnt,
                                                           std::size_t kk, double* out_r2,
                                                           std::vector<std::uint32_t>& seen) const {
    const double inf = std::numeric_limits<double>::infinity();
    alignas(64) double qc[3][8];
    for (std::uint32_t l = 0; l < 8; ++l) {
      const double* p = pts_.data() + static_cast<std::size_t>(p0 + std::min(l, cnt - 1)) * 3;
      for (int j = 0; j < 3; ++j) qc[j][l] = p[j];
    }
    const __m512d qx = _mm512_load_pd(qc[0]);
    const __m512d qy = _mm512_load_pd(qc[1]);
    const __m512d qz = _mm512_load_pd(qc[2]);
    __m512d v[kL];
    for (int i = 0; i < kL; ++i) {
      v[i] = _mm512_set1_pd(static_cast<std::size_t>(i) < kL - kk ? -inf : inf);
    }
    struct alignas(64) Entry {
      __m512d box2;
      std::uint32_t node;
    };
    Entry stack[128];
    const std::uint32_t start = group_start(p0, cnt);
    // The start node's subtree, then each ancestor's other child's subtree.
    for (std::uint32_t c = start, root = start;;) {
      int top = 0;
      stack[top++] = {root == start ? _mm512_setzero_pd() : box2_avx512(root, qx, qy, qz), root};
      while (top > 0) {
        const Entry en = stack[--top];
        if (_mm512_cmp_pd_mask(en.box2, v[kL - 1], _CMP_LE_OQ) == 0) continue;
        const Node& nd = nodes_[en.node];
        if (nd.left < 0) {
          seen.push_back(en.node);
          const double* p = pts_.data() + static_cast<std::size_t>(nd.begin) * 3;
          for (auto t = nd.begin; t < nd.end; ++t, p += 3) {
            const __m512d dx = _mm512_sub_pd(_mm512_set1_pd(p[0]), qx);
            const __m512d dy = _mm512_sub_pd(_mm512_set1_pd(p[1]), qy);
            const __m512d dz = _mm512_sub_pd(_mm512_set1_pd(p[2]), qz);
            __m512d d2 = no_contract_v512(_mm512_mul_pd(dx, dx));
            d2 = _mm512_add_pd(d2, no_contract_v512(_mm512_mul_pd(dy, dy)));
            d2 = _mm512_add_pd(d2, no_contract_v512(_mm512_mul_pd(dz, dz)));
#pragma GCC unroll 16
            for (int i = kL - 1; i > 0; --i) {
              v[i] = _mm512_min_pd(v[i], _mm512_max_pd(v[i - 1], d2));
            }
            v[0] = _mm512_min_pd(v[0], d2);
          }
          continue;
        }
        const auto l = static_cast<std::uint32_t>(nd.left);
        const auto r = static_cast<std::uint32_t>(nd.right);
        const Entry el{box2_avx512(l, qx, qy, qz), l};
        const Entry er{box2_avx512(r, qx, qy, qz), r};
        const bool keep_l = _mm512_cmp_pd_mask(el.box2, v[kL - 1], _CMP_LE_OQ) != 0;
        const bool keep_r = _mm512_cmp_pd_mask(er.box2, v[kL - 1], _CMP_LE_OQ) != 0;
        // Nearer child (by lane 0) on top.
        if (_mm512_cvtsd_f64(el.box2) <= _mm512_cvtsd_f64(er.box2)) {
          if (keep_r) stack[top++] = er;
          if (keep_l) stack[top++] = el;
        } else {
          if (keep_l) stack[top++] = el;
          if (keep_r) stack[top++] = er;
        }
      }
      if (nodes_[c].parent < 0) break;
      const auto p = static_cast<std::uint32_t>(nodes_[c].parent);
      const Node& pn = nodes_[p];
      root =
          static_cast<std::uint32_t>(pn.left == static_cast<std::int32_t>(c) ? pn.right : pn.left);
      c = p;
    }
    alignas(64) double r[8];
    _mm512_store_pd(r, v[kL - 1]);
    for (std::uint32_t l = 0; l < cnt; ++l) out_r2[l] = r[l];
  }
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

  // Pass 2 of knn_and_seeds for a group of up to kW tree positions p0 .. p0 + cnt - 1, one per
  // lane (kW = 8: AVX-512F, 4: AVX2): seed_query for all of them at once over their group's
  // scanned leaves `near` (tree order). Every candidate t of a leaf is tested in all lanes: in
  // the core ball (d² <= r², computed as in seed_query), t != s, and max{core(s), core(t)}
  // strictly below the lane's best. Candidates come in increasing tree position, so strict
  // improvement gives the lightest edge with the smallest position, seed_query's rule. A leaf is
  // skipped when no lane can improve (its box beyond r², or max{core(s), min core} >= best).
#if defined(__AVX2__)
  void seed_group_avx2(std::uint32_t p0, std::uint32_t cnt, const std::vector<std::uint32_t>& near,
                       const double* r2) {
    alignas(32) double qc[3][4], rs[4], cs[4], sp[4];
    for (std::uint32_t l = 0; l < 4; ++l) {
      const std::uint32_t s = p0 + std::min(l, cnt - 1);
      for (int j = 0; j < 3; ++j) qc[j][l] = pts_[static_cast<std::size_t>(s) * 3 + j];
      rs[l] = r2[s - p0];
      cs[l] = core_[s];
      sp[l] = static_cast<double>(s);
    }
    const __m256d qx = _mm256_load_pd(qc[0]), qy = _mm256_load_pd(qc[1]);
    const __m256d qz = _mm256_load_pd(qc[2]), vrs = _mm256_load_pd(rs);
    const __m256d vcs = _mm256_load_pd(cs), vs = _mm256_load_pd(sp);
    const __m256d zero = _mm256_setzero_pd();
    __m256d bw = _mm256_set1_pd(std::numeric_limits<double>::infinity());
    __m256d bt = zero;
    for (const auto leaf : near) {
      const Node& nd = nodes_[leaf];
      const double* lo = lo_.data() + static_cast<std::size_t>(leaf) * 3;
      const double* hi = hi_.data() + static_cast<std::size_t>(leaf) * 3;
      const __m256d gx = _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo), qx),
                                                     _mm256_sub_pd(qx, _mm256_broadcast_sd(hi))),
                                       zero);
      const __m256d gy =
          _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo + 1), qy),
                                      _mm256_sub_pd(qy, _mm256_broadcast_sd(hi + 1))),
                        zero);
      const __m256d gz =
          _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo + 2), qz),
                                      _mm256_sub_pd(qz, _mm256_broadcast_sd(hi + 2))),
                        zero);
      __m256d b2 = no_contract_simd(_mm256_mul_pd(gx, gx));
      b2 = _mm256_add_pd(b2, no_contract_simd(_mm256_mul_pd(gy, gy)));
      b2 = _mm256_add_pd(b2, no_contract_simd(_mm256_mul_pd(gz, gz)));
      const __m256d lb = _mm256_max_pd(vcs, _mm256_set1_pd(nd.min_core));
      const __m256d can =
          _mm256_and_pd(_mm256_cmp_pd(b2, vrs, _CMP_LE_OQ), _mm256_cmp_pd(lb, bw, _CMP_LT_OQ));
      if (_mm256_movemask_pd(can) == 0) continue;
      const double* p = pts_.data() + static_cast<std::size_t>(nd.begin) * 3;
      for (auto t = nd.begin; t < nd.end; ++t, p += 3) {
        const __m256d dx = _mm256_sub_pd(_mm256_broadcast_sd(p), qx);
        const __m256d dy = _mm256_sub_pd(_mm256_broadcast_sd(p + 1), qy);
        const __m256d dz = _mm256_sub_pd(_mm256_broadcast_sd(p + 2), qz);
        __m256d d2 = no_contract_simd(_mm256_mul_pd(dx, dx));
        d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dy, dy)));
        d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dz, dz)));
        const __m256d tv = _mm256_set1_pd(static_cast<double>(t));
        const __m256d w = _mm256_max_pd(vcs, _mm256_set1_pd(core_[t]));
        const __m256d take = _mm256_and_pd(
            _mm256_and_pd(_mm256_cmp_pd(d2, vrs, _CMP_LE_OQ), _mm256_cmp_pd(w, bw, _CMP_LT_OQ)),
            _mm256_cmp_pd(tv, vs, _CMP_NEQ_OQ));
        bw = _mm256_blendv_pd(bw, w, take);
        bt = _mm256_blendv_pd(bt, tv, take);
      }
    }
    alignas(32) double ow[4], ot[4];
    _mm256_store_pd(ow, bw);
    _mm256_store_pd(ot, bt);
    for (std::uint32_t l = 0; l < cnt; ++l) {
      cand_w_[p0 + l] = ow[l];
      cand_t_[p0 + l] = static_cast<std::uint32_t>(ot[l]);
    }
  }
#endif

#if defined(DS3D_HDBSCAN_AVX512)
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
  __attribute__((target("avx512f"))) void seed_group_avx512(std::uint32_t p0, std::uint32_t cnt,
                                                            const std::vector<std::uint32_t>& near,
                                                            const double* r2) {
    alignas(64) double qc[3][8], rs[8], cs[8], sp[8];
    for (std::uint32_t l = 0; l < 8; ++l) {
      const std::uint32_t s = p0 + std::min(l, cnt - 1);
      for (int j = 0; j < 3; ++j) qc[j][l] = pts_[static_cast<std::size_t>(s) * 3 + j];
      rs[l] = r2[s - p0];
      cs[l] = core_[s];
      sp[l] = static_cast<double>(s);
    }
    const __m512d qx = _mm512_load_pd(qc[0]), qy = _mm512_load_pd(qc[1]);
    const __m512d qz = _mm512_load_pd(qc[2]), vrs = _mm512_load_pd(rs);
    const __m512d vcs = _mm512_load_pd(cs), vs = _mm512_load_pd(sp);
    __m512d bw = _mm512_set1_pd(std::numeric_limits<double>::infinity());
    __m512d bt = _mm512_setzero_pd();
    for (const auto leaf : near) {
      const Node& nd = nodes_[leaf];
      const __m512d b2 = box2_avx512(leaf, qx, qy, qz);
      const __m512d lb = _mm512_max_pd(vcs, _mm512_set1_pd(nd.min_core));
      const __mmask8 can =
          _mm512_cmp_pd_mask(b2, vrs, _CMP_LE_OQ) & _mm512_cmp_pd_mask(lb, bw, _CMP_LT_OQ);
      if (can == 0) continue;
      const double* p = pts_.data() + static_cast<std::size_t>(nd.begin) * 3;
      for (auto t = nd.begin; t < nd.end; ++t, p += 3) {
        const __m512d dx = _mm512_sub_pd(_mm512_set1_pd(p[0]), qx);
        const __m512d dy = _mm512_sub_pd(_mm512_set1_pd(p[1]), qy);
        const __m512d dz = _mm512_sub_pd(_mm512_set1_pd(p[2]), qz);
        __m512d d2 = no_contract_v512(_mm512_mul_pd(dx, dx));
        d2 = _mm512_add_pd(d2, no_contract_v512(_mm512_mul_pd(dy, dy)));
        d2 = _mm512_add_pd(d2, no_contract_v512(_mm512_mul_pd(dz, dz)));
        const __m512d tv = _mm512_set1_pd(static_cast<double>(t));
        const __m512d w = _mm512_max_pd(vcs, _mm512_set1_pd(core_[t]));
        const __mmask8 take = _mm512_cmp_pd_mask(d2, vrs, _CMP_LE_OQ) &
                              _mm512_cmp_pd_mask(w, bw, _CMP_LT_OQ) &
                              _mm512_cmp_pd_mask(tv, vs, _CMP_NEQ_OQ);
        bw = _mm512_mask_blend_pd(take, bw, w);
        bt = _mm512_mask_blend_pd(take, bt, tv);
      }
    }
    alignas(64) double ow[8], ot[8];
    _mm512_store_pd(ow, bw);
    _mm512_store_pd(ot, bt);
    for (std::uint32_t l = 0; l < cnt; ++l) {
      cand_w_[p0 + l] = ow[l];
      cand_t_[p0 + l] = static_cast<std::uint32_t>(ot[l]);
    }
  }
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

  // Core distances and first candidate edges, both exact.
  // 1. core(s) = sqrt of the kk-th smallest squared distance from s, itself included (the
  //    distance to its k-th nearest other point), by walk_from_leaf, skipping boxes at or
  //    beyond the current kk-th value. Box distances are exact lower
  //    bounds (monotone rounding), so this is bitwise brute force, whatever the tie order.
  // 2. The seed of s is the cheapest edge to a point of its core ball {t != s: d²(s,t) <= r²},
  //    r² = that kk-th squared distance. There d(s,t) <= core(s), so the edge weighs
  //    max{core(s), core(t)}; ties go to the smallest tree position. The ball is the k-nearest
  //    list unless several points tie at the k-th distance (then it holds all of them, so the
  //    seed no longer depends on how a kNN search orders ties). When some core(t) <= core(s)
  //    the seed weighs core(s), a lower bound of every edge of s: it is optimal.
  // Queries run leaf by leaf, each writing only its own outputs: identical for any thread count.
  void knn_and_seeds(std::size_t kk) {
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> r2(n_);
    // Query units: groups of `width` consecutive tree positions searched in one walk, one per
    // SIMD lane (knn_group_avx512: 8, knn_group_avx2: 4; D = 3, kk <= 16, see KnnLanes), else
    // leaves (per-query walks). unit_begin[u] is the first tree position of unit u; near[u]
    // lists, in tree order, the leaves scanned for its queries. kl: list registers per lane.
    [[maybe_unused]] const std::size_t kl = kk <= 4 ? 4 : kk <= 8 ? 8 : kk <= 12 ? 12 : 16;
    const std::size_t width = knn_lane_width(dim_, kk, lanes_);  // 0 = per-query search
    std::vector<std::uint32_t> unit_begin;
    if (width > 0) {
      unit_begin.reserve(n_ / width + 2);
      for (std::size_t p = 0; p < n_; p += width) {
        unit_begin.push_back(static_cast<std::uint32_t>(p));
      }
    } else {
      for (const auto leaf : leaves_) unit_begin.push_back(nodes_[leaf].begin);
    }
    const std::size_t units = unit_begin.size();
    unit_begin.push_back(static_cast<std::uint32_t>(n_));
    std::vector<std::vector<std::uint32_t>> near(seeds_ || width == 0 ? units : 0);
    cand_w_.assign(n_, inf);
    cand_t_.assign(n_, 0U);
    const std::size_t chunks = std::size_t{16} * static_cast<std::size_t>(std::max(1, threads_));
    parallel_chunks(units, chunks, threads_, [&](std::size_t b, std::size_t e, std::size_t) {
      if (width > 0) {
        std::vector<std::uint32_t> scratch;  // scanned leaves when no seeds are wanted
        for (std::size_t u = b; u < e; ++u) {
          const auto p0 = unit_begin[u];
          const auto cnt = unit_begin[u + 1] - p0;
          double* out = r2.data() + p0;
          auto& seen = seeds_ ? near[u] : scratch;
          if (width == 8) {
#if defined(DS3D_HDBSCAN_AVX512)
            switch (kl) {
              case 4:
                knn_group_avx512<4>(p0, cnt, kk, out, seen);
                break;
              case 8:
                knn_group_avx512<8>(p0, cnt, kk, out, seen);
                break;
              case 12:
                knn_group_avx512<12>(p0, cnt, kk, out, seen);
                break;
              default:
                knn_group_avx512<16>(p0, cnt, kk, out, seen);
                break;
            }
#endif
          } else {
#if defined(__AVX2__)
            switch (kl) {
              case 4:
                knn_group_avx2<4>(p0, cnt, kk, out, seen);
                break;
              case 8:
                knn_group_avx2<8>(p0, cnt, kk, out, seen);
                break;
              case 12:
                knn_group_avx2<12>(p0, cnt, kk, out, seen);
                break;
              default:
                knn_group_avx2<16>(p0, cnt, kk, out, seen);
                break;
            }
#endif
          }
          for (auto s = p0; s < p0 + cnt; ++s) core_[s] = std::sqrt(r2[s]);
          if (!seeds_) {
            scratch.clear();
            continue;
          }
          std::sort(near[u].begin(), near[u].end());  // leaf ids in preorder = tree order
        }
        return;
      }
      std::vector<double> bd((kk + 3) & ~std::size_t{3});  // slots for knn_scan_avx2
      std::vector<std::uint32_t> mark(nodes_.size(), 0U);
      for (std::size_t li = b; li < e; ++li) {
        const auto leaf = leaves_[li];
        const Node& ln = nodes_[leaf];
        auto& seen = near[li];
        for (auto s = ln.begin; s < ln.end; ++s) {
          knn_query(s, leaf, kk, bd.data(), seen, mark, static_cast<std::uint32_t>(li + 1));
          r2[s] = bd[kk - 1];
          core_[s] = std::sqrt(bd[kk - 1]);
        }
        std::sort(seen.begin(), seen.end());  // leaf ids in preorder = tree order
      }
    });
    if (!seeds_) return;
    for (std::size_t k = nodes_.size(); k-- > 0;) {
      auto& nd = nodes_[k];
      if (nd.left < 0) {
        double m = inf;
        for (auto i = nd.begin; i < nd.end; ++i) m = std::min(m, core_[i]);
        nd.min_core = m;
      } else {
        nd.min_core = std::min(nodes_[static_cast<std::size_t>(nd.left)].min_core,
                               nodes_[static_cast<std::size_t>(nd.right)].min_core);
      }
    }
    parallel_chunks(units, chunks, threads_, [&](std::size_t b, std::size_t e, std::size_t) {
      for (std::size_t u = b; u < e; ++u) {
        const auto p0 = unit_begin[u];
#if defined(DS3D_HDBSCAN_AVX512)
        if (width == 8) {
          seed_group_avx512(p0, unit_begin[u + 1] - p0, near[u], r2.data() + p0);
          continue;
        }
#endif
#if defined(__AVX2__)
        if (width == 4) {
          seed_group_avx2(p0, unit_begin[u + 1] - p0, near[u], r2.data() + p0);
          continue;
        }
#endif
        for (auto s = p0; s < unit_begin[u + 1]; ++s) {
          double best_w = inf;
          std::uint32_t best_t = 0;
          seed_query(s, near[u].data(), near[u].size(), r2[s], best_w, best_t);
          cand_w_[s] = best_w;
          cand_t_[s] = best_t;
        }
      }
    });
  }

  std::int32_t build_node(const double* data, std::vector<std::uint32_t>& order, std::uint32_t b,
                          std::uint32_t e) {
    const auto id = static_cast<std::int32_t>(nodes_.size());
    nodes_.push_back({b, e, -1, -1, 0.0, kMixed, -1});
    lo_.resize(nodes_.size() * dim_);
    hi_.resize(nodes_.size() * dim_);
    double* lo = lo_.data() + static_cast<std::size_t>(id) * dim_;
    double* hi = hi_.data() + static_cast<std::size_t>(id) * dim_;
    for (std::size_t j = 0; j < dim_; ++j) {
      lo[j] = std::numeric_limits<double>::infinity();
      hi[j] = -std::numeric_limits<double>::infinity();
    }
    if (dim_ == 3) {  // the loop below with the box in registers (same min/max sequence)
      extend_box3(data, order.data(), b, e, lo, hi);
    } else {
      for (auto i = b; i < e; ++i) {
        for (std::size_t j = 0; j < dim_; ++j) {
          const double v = data[order[i] * dim_ + j];
          lo[j] = std::min(lo[j], v);
          hi[j] = std::max(hi[j], v);
        }
      }
    }
    if (e - b <= kLeafSize) return id;
    std::size_t split = 0;
    for (std::size_t j = 1; j < dim_; ++j) {
      if (hi[j] - lo[j] > hi[split] - lo[split]) split = j;
    }
    if (!(hi[split] > lo[split])) return id;  // all points identical: keep as one leaf
    const auto mid = b + (e - b) / 2;
    // nth_element on (split coordinate, id) pairs compared by the coordinate: the same
    // comparisons in the same order as on the ids with an indirect comparator, so the same
    // permutation (the tree, and with it every tie rule, is unchanged), without a dependent
    // load in each comparison.
    // Nodes above kKeyedMax points (only for n > kKeyedMax) keep the indirect comparator, so
    // the scratch stays at most 1 MiB.
    if (e - b <= kKeyedMax) {
      auto* kv = keyed_.data();
      for (auto i = b; i < e; ++i) kv[i - b] = {data[order[i] * dim_ + split], order[i]};
      std::nth_element(kv, kv + (mid - b), kv + (e - b),
                       [](const std::pair<double, std::uint32_t>& x,
                          const std::pair<double, std::uint32_t>& y) { return x.first < y.first; });
      for (auto i = b; i < e; ++i) order[i] = kv[i - b].second;
    } else {
      std::nth_element(order.begin() + b, order.begin() + mid, order.begin() + e,
                       [&](std::uint32_t x, std::uint32_t y) {
                         return data[x * dim_ + split] < data[y * dim_ + split];
                       });
    }
    const auto l = build_node(data, order, b, mid);
    const auto r = build_node(data, order, mid, e);
    nodes_[static_cast<std::size_t>(id)].left = l;
    nodes_[static_cast<std::size_t>(id)].right = r;
    nodes_[static_cast<std::size_t>(l)].parent = id;
    nodes_[static_cast<std::size_t>(r)].parent = id;
    return id;
  }

  // Marks every node whose points all lie in one component, and records for each tree position
  // the largest such node with more than one point that starts there (nodes_ is in preorder, so
  // the first one met is the largest).
  void label_nodes(const std::vector<std::uint32_t>& comp) {
    for (std::size_t k = nodes_.size(); k-- > 0;) {
      auto& nd = nodes_[k];
      if (nd.left < 0) {
        std::uint32_t c = comp[nd.begin];
        for (auto i = nd.begin + 1; i < nd.end && c != kMixed; ++i) {
          if (comp[i] != c) c = kMixed;
        }
        nd.comp = c;
      } else {
        const auto cl = nodes_[static_cast<std::size_t>(nd.left)].comp;
        nd.comp = cl == nodes_[static_cast<std::size_t>(nd.right)].comp ? cl : kMixed;
      }
    }
    pure_start_.assign(n_, -1);
    for (std::size_t k = 0; k < nodes_.size(); ++k) {
      const auto& nd = nodes_[k];
      if (nd.comp != kMixed && nd.end - nd.begin > 1 && pure_start_[nd.begin] < 0) {
        pure_start_[nd.begin] = static_cast<std::int32_t>(k);
      }
    }
  }

  // Queries the points of node k (all in component c, in tree order) with the same effect as
  // calling query() on each of them in turn, but first tries to prove for the whole node at
  // once that no point of another component can give any of them an edge below `bound`
  // (far_from_others). Then every query would find nothing, and its only effect, the lower
  // bound update, is applied directly. Bounds only decrease, so a proof for the node also
  // holds for each point's own, possibly smaller, bound.
  void process_node(std::size_t k, std::uint32_t c, double& bound) {
    const Node& nd = nodes_[k];
    if (far_from_others(k, c, bound)) {
      for (auto i = nd.begin; i < nd.end; ++i) {
        // query()'s early exits, then its "nothing found" update (bound0 = bound here, as the
        // component bound never exceeds a member's own candidate).
        if (cand_w_[i] == core_[i] || lower_[i] >= bound || core_[i] >= bound) continue;
        lower_[i] = std::max(lower_[i], bound);
      }
      return;
    }
    if (nd.left < 0) {
      for (auto i = nd.begin; i < nd.end; ++i) query(i, bound);
      return;
    }
    process_node(static_cast<std::size_t>(nd.left), c, bound);
    process_node(static_cast<std::size_t>(nd.right), c, bound);
  }

  // Squared distance between the boxes of nodes a and b: a lower bound of every computed
  // sq_dist_seq between their points, by monotone rounding (as box_dist2).
  [[nodiscard]] double box_box_dist2(std::size_t a, std::size_t b) const {
    const double* alo = lo_.data() + a * dim_;
    const double* ahi = hi_.data() + a * dim_;
    const double* blo = lo_.data() + b * dim_;
    const double* bhi = hi_.data() + b * dim_;
    double s = 0.0;
    for (std::size_t j = 0; j < dim_; ++j) {
      const double d = gap(blo[j] - ahi[j], alo[j] - bhi[j]);
      s += no_contract(d * d);
    }
    return s;
  }

  // True when query() of any point of node k (component c) with a bound <= `bound` provably
  // accepts no edge: every point of another component is pruned by the same tests query()
  // applies (κ lower bound >= bound, or squared distance above bound²·(1 + 1e-14)), here taken
  // for the node's box and its smallest core distance.
  [[nodiscard]] bool far_from_others(std::size_t k, std::uint32_t c, double bound) const {
    const double hi2 = bound * bound * (1.0 + 1e-14);
    const double qcore = nodes_[k].min_core;
    if (qcore >= bound) return true;
    std::int32_t stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const auto r = static_cast<std::size_t>(stack[--top]);
      const Node& nd = nodes_[r];
      if (nd.comp == c || nd.min_core >= bound) continue;
      if (box_box_dist2(k, r) > hi2) continue;
      if (nd.left < 0) {
        for (auto i = nd.begin; i < nd.end; ++i) {
          if (comp_[i] == c || core_[i] >= bound) continue;
          if (box_dist2(pts_.data() + static_cast<std::size_t>(i) * dim_, k) <= hi2) return false;
        }
        continue;
      }
      stack[top++] = nd.right;
      stack[top++] = nd.left;
    }
    return true;
  }

  // Squared distance from q to node k's box: a lower bound of every computed sq_dist_seq to its
  // points, because each rounding step is monotone.
  [[nodiscard]] double box_dist2(const double* q, std::size_t k) const {
    const double* lo = lo_.data() + k * dim_;
    const double* hi = hi_.data() + k * dim_;
    if (dim_ == 3) {  // the loop below with the gaps in one vector (same operations and order)
#if defined(__AVX2__)
      const __m256i m3 = _mm256_set_epi64x(0, -1, -1, -1);
      const __m256d vq = _mm256_maskload_pd(q, m3);
      const __m256d a = _mm256_sub_pd(_mm256_maskload_pd(lo, m3), vq);
      const __m256d b = _mm256_sub_pd(vq, _mm256_maskload_pd(hi, m3));
      const __m256d g = _mm256_max_pd(_mm256_max_pd(a, b), _mm256_setzero_pd());
      const __m256d g2 = no_contract_simd(_mm256_mul_pd(g, g));
      const __m128d g01 = _mm256_castpd256_pd128(g2);
      double s = 0.0 + _mm_cvtsd_f64(g01);
      s += _mm_cvtsd_f64(_mm_unpackhi_pd(g01, g01));
      return s + _mm_cvtsd_f64(_mm256_extractf128_pd(g2, 1));
#else
      const double g0 = gap(lo[0] - q[0], q[0] - hi[0]);
      const double g1 = gap(lo[1] - q[1], q[1] - hi[1]);
      const double g2 = gap(lo[2] - q[2], q[2] - hi[2]);
      double s = 0.0 + no_contract(g0 * g0);
      s += no_contract(g1 * g1);
      return s + no_contract(g2 * g2);
#endif
    }
    double s = 0.0;
    for (std::size_t j = 0; j < dim_; ++j) {
      const double a = lo[j] - q[j];
      const double b = q[j] - hi[j];
      const double d = gap(a, b);
      s += no_contract(d * d);
    }
    return s;
  }

  // box_dist2(q, a) and box_dist2(q, b) (bitwise: for D = 3 with AVX2 both boxes' gaps are
  // squared in two vectors whose fourth lane is 0, and one horizontal add gives
  // (g0² + g1²) + g2² for each, box_dist2's order).
  void box_dist2_pair(const double* q, std::size_t a, std::size_t b, double& da, double& db) const {
#if defined(__AVX2__)
    if (dim_ == 3) {
      const __m256i m3 = _mm256_set_epi64x(0, -1, -1, -1);
      const __m256d vq = _mm256_maskload_pd(q, m3);
      const __m256d zero = _mm256_setzero_pd();
      auto gap2 = [&](std::size_t k) {
        const __m256d lo = _mm256_maskload_pd(lo_.data() + k * 3, m3);
        const __m256d hi = _mm256_maskload_pd(hi_.data() + k * 3, m3);
        const __m256d g =
            _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(lo, vq), _mm256_sub_pd(vq, hi)), zero);
        return no_contract_simd(_mm256_mul_pd(g, g));
      };
      const __m256d h = _mm256_hadd_pd(gap2(a), gap2(b));  // [a0+a1, b0+b1, a2+0, b2+0]
      const __m128d sum = _mm_add_pd(_mm256_castpd256_pd128(h), _mm256_extractf128_pd(h, 1));
      da = _mm_cvtsd_f64(sum);
      db = _mm_cvtsd_f64(_mm_unpackhi_pd(sum, sum));
      return;
    }
#endif
    da = box_dist2(q, a);
    db = box_dist2(q, b);
  }

  // Improves point qi's candidate edge given `comp_bound`, the best edge weight known for its
  // component (tightened in place). Only strictly better edges are accepted.
  void query(std::size_t qi, double& comp_bound) {
    const std::uint32_t cq = comp_[qi];
    const double cqore = core_[qi];
    const double own = cand_w_[qi];
    if (own == cqore) return;  // κ(q) is a lower bound of every edge of q: optimal already
    // lower_[qi] bounds q's cheapest edge to another component from below; it stays valid
    // across rounds because merging only removes candidates.
    if (lower_[qi] >= comp_bound) return;
    const double bound0 = std::min(own, comp_bound);
    if (cqore >= bound0) return;  // cannot beat the component's best edge
    const double* q = pts_.data() + qi * dim_;
    double bound = bound0;
    std::uint32_t best_t = cand_t_[qi];
    bool improved = false;
    // Squared-space pruning without sqrt: any d² above hi2 = bound²·(1 + 1e-14) has
    // sqrt(d²) > bound even after rounding, so it cannot give a better edge; values at or
    // below hi2 are decided exactly with sqrt.
    auto hi2_of = [](double b) { return b * b * (1.0 + 1e-14); };
    double hi2 = hi2_of(bound);
    struct Entry {
      std::int32_t node;
      double lbc;   // max{κ(q), min κ in node}
      double box2;  // squared distance from q to the node's box (lower bound of d²)
    };
    Entry stack[128];
    int top = 0;
    stack[top++] = {0, std::max(cqore, nodes_[0].min_core), 0.0};
    while (top > 0) {
      const Entry en = stack[--top];
      if (en.lbc >= bound || en.box2 > hi2) continue;
      const Node& nd = nodes_[static_cast<std::size_t>(en.node)];
      if (nd.comp == cq) continue;
      if (nd.left < 0) {
        for (auto i = nd.begin; i < nd.end; ++i) {
          if (comp_[i] == cq) continue;
          const double lo = cqore > core_[i] ? cqore : core_[i];
          if (lo >= bound) continue;
          const double d2 = sq_dist_seq(q, pts_.data() + static_cast<std::size_t>(i) * dim_, dim_);
          if (d2 > hi2) continue;
          const double d = std::sqrt(d2);
          const double mr = d > lo ? d : lo;
          if (mr < bound) {
            bound = mr;
            hi2 = hi2_of(bound);
            best_t = i;
            improved = true;
          }
        }
        continue;
      }
      const auto l = static_cast<std::size_t>(nd.left);
      const auto r = static_cast<std::size_t>(nd.right);
      double bl = 0.0;
      double br = 0.0;
      box_dist2_pair(q, l, r, bl, br);
      const Entry el{nd.left, std::max(cqore, nodes_[l].min_core), bl};
      const Entry er{nd.right, std::max(cqore, nodes_[r].min_core), br};
      const bool keep_l = el.lbc < bound && el.box2 <= hi2;
      const bool keep_r = er.lbc < bound && er.box2 <= hi2;
      // Push the farther child first so the nearer one is searched first.
      if (el.box2 <= er.box2) {
        if (keep_r) stack[top++] = er;
        if (keep_l) stack[top++] = el;
      } else {
        if (keep_l) stack[top++] = el;
        if (keep_r) stack[top++] = er;
      }
    }
    if (improved) {
      cand_w_[qi] = bound;
      cand_t_[qi] = best_t;
      comp_bound = std::min(comp_bound, bound);
      lower_[qi] = bound;  // exact: nothing cheaper exists
    } else {
      lower_[qi] = std::max(lower_[qi], bound0);  // the search proved nothing below bound0
    }
  }

  std::size_t n_, dim_;
  int threads_;
  KnnLanes lanes_;
  bool seeds_ = true;                // knn_and_seeds also seeds the candidate edges
  std::vector<std::uint32_t> perm_;  // tree position -> point id
  std::vector<double> pts_;          // coordinates in tree order
  std::vector<double> core_;         // core distances in tree order
  std::vector<Node> nodes_;
  std::vector<double> lo_, hi_;
  std::vector<std::pair<double, std::uint32_t>> keyed_;  // build scratch: (coordinate, id)
  std::vector<double> soa_;            // coordinates per dimension: soa_[j * stride_ + position]
  std::size_t stride_ = 0;             // n_ + kLeafSize (zero padding)
  std::vector<std::uint32_t> leaves_;  // leaf node ids in tree order
  std::vector<std::uint32_t> uf_parent_;
  std::vector<double> cand_w_;            // per tree position: best known edge weight
  std::vector<double> lower_;             // ... and a lower bound of the best edge weight
  std::vector<std::uint32_t> cand_t_;     // ... and its target (tree position)
  std::vector<std::int32_t> pure_start_;  // per tree position: largest one-component node from it
  const std::uint32_t* comp_ = nullptr;
};

// Core distances (k-th nearest other point, 1 <= k < n) into `core` and the MST by KD-tree
// Borůvka, sharing one tree.
inline std::vector<MstEdge> boruvka_kdtree(const double* data, std::size_t n, std::size_t dim,
                                           std::size_t k, int num_threads,
                                           std::vector<double>& core,
                                           KnnLanes lanes = KnnLanes::kAuto) {
  if (n < 2) {
    core.assign(n, 0.0);
    return {};
  }
  BoruvkaKdTree t(data, n, dim, k, num_threads, lanes);
  core = t.core_distances();
  return t.run();
}

// Core distances (k-th nearest other point, 1 <= k < n) only, by BoruvkaKdTree's search.
inline std::vector<double> boruvka_core_distances(const double* data, std::size_t n,
                                                  std::size_t dim, std::size_t k, int num_threads,
                                                  KnnLanes lanes = KnnLanes::kAuto) {
  if (n < 2) return std::vector<double>(n, 0.0);
  return BoruvkaKdTree(data, n, dim, k, num_threads, lanes, false).core_distances();
}

}  // namespace ds3d::detail
