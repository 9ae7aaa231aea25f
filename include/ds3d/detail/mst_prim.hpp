// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Prim's MST on the implicit dense mutual-reachability graph (SoA slots, SSE2 / AVX2 / AVX-512F
// steps for D = 3) and on a precomputed distance matrix. Not API: see ds3d/detail/mst.hpp.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include "ds3d/detail/mst.hpp"

namespace ds3d::detail {

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

// One slot of a 3-D step's scalar tail: updates its key with the new tree point (coords c,
// squared core cc2, id cur) and returns the key. kNoContract is the calling step's product
// barrier (its tail's arithmetic, unchanged).
template <double (*kNoContract)(double)>
inline double prim_update_slot(PrimSoA& s, const double* c, double cc2, double cur, std::size_t t) {
  const double* core2 = s.core2;
  double* key = s.key2;
  double* from = s.from;
  double d2 = 0.0;
  for (std::size_t j = 0; j < 3; ++j) {
    const double diff = s.coords[j][t] - c[j];
    d2 += kNoContract(diff * diff);
  }
  const double lo = cc2 > core2[t] ? cc2 : core2[t];
  const double m2 = d2 > lo ? d2 : lo;
  if (m2 < key[t]) {
    key[t] = m2;
    from[t] = cur;
  }
  return key[t];
}

// Scalar tail of the SSE2 and AVX2 steps: slots t .. s.m - 1, keeping the first smallest key
// (best) and its slot (best_t).
template <double (*kNoContract)(double)>
inline void prim_tail_first_min(PrimSoA& s, const double* c, double cc2, double cur, std::size_t t,
                                double& best, double& best_t) {
  for (; t < s.m; ++t) {
    const double k = prim_update_slot<kNoContract>(s, c, cc2, cur, t);
    if (k < best) {
      best = k;
      best_t = static_cast<double>(t);
    }
  }
}

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
  prim_tail_first_min<no_contract>(s, c, cc2, cur, t, best, best_t);
  return best_t < 0.0 ? s.m : static_cast<std::size_t>(best_t);
}
#endif

#if defined(DS3D_HDBSCAN_AVX2)
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
  prim_tail_first_min<no_contract_x86>(s, c, cc2, cur, t, best, best_t);
  return best_t < 0.0 ? s.m : static_cast<std::size_t>(best_t);
}

#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
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
    const double k = prim_update_slot<no_contract_x86>(s, c, cc2, cur, t);
    if (k < best) best = k;
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
#endif

inline std::vector<MstEdge> prim_dense(const double* data, std::size_t n, std::size_t dim,
                                       const std::vector<double>& core, PrimStep step) {
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

}  // namespace ds3d::detail
