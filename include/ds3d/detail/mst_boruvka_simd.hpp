// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// BoruvkaKdTree's core-distance and seed passes for 3-D points with one query per SIMD lane
// (AVX2: 4, AVX-512F: 8). Out-of-class members of mst_boruvka.hpp. Not API: see
// ds3d/detail/mst.hpp.

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include "ds3d/detail/mst_boruvka.hpp"

namespace ds3d::detail {

// Pass 1 for one lane group of knn_and_seeds: knn_group_avx512 (width 8) or knn_group_avx2,
// with the list in kl = kk rounded up to 4, 8, 12 or 16 registers per lane.
inline void BoruvkaKdTree::knn_group([[maybe_unused]] std::size_t width,
                                     [[maybe_unused]] std::uint32_t p0,
                                     [[maybe_unused]] std::uint32_t cnt,
                                     [[maybe_unused]] std::size_t kk,
                                     [[maybe_unused]] double* out_r2,
                                     [[maybe_unused]] std::vector<std::uint32_t>& seen) const {
  [[maybe_unused]] const std::size_t kl = kk <= 4 ? 4 : kk <= 8 ? 8 : kk <= 12 ? 12 : 16;
  if (width == 8) {
#if defined(DS3D_HDBSCAN_AVX512)
    switch (kl) {
      case 4:
        knn_group_avx512<4>(p0, cnt, kk, out_r2, seen);
        break;
      case 8:
        knn_group_avx512<8>(p0, cnt, kk, out_r2, seen);
        break;
      case 12:
        knn_group_avx512<12>(p0, cnt, kk, out_r2, seen);
        break;
      default:
        knn_group_avx512<16>(p0, cnt, kk, out_r2, seen);
        break;
    }
#endif
  } else {
#if defined(__AVX2__)
    switch (kl) {
      case 4:
        knn_group_avx2<4>(p0, cnt, kk, out_r2, seen);
        break;
      case 8:
        knn_group_avx2<8>(p0, cnt, kk, out_r2, seen);
        break;
      case 12:
        knn_group_avx2<12>(p0, cnt, kk, out_r2, seen);
        break;
      default:
        knn_group_avx2<16>(p0, cnt, kk, out_r2, seen);
        break;
    }
#endif
  }
}

// Coordinates of the kW queries of a lane group, by axis: tree positions p0 .. p0 + cnt - 1,
// missing lanes repeating the last one.
template <std::uint32_t kW>
inline void BoruvkaKdTree::lane_points(std::uint32_t p0, std::uint32_t cnt,
                                       double (&qc)[3][kW]) const {
  for (std::uint32_t l = 0; l < kW; ++l) {
    const double* p = pts_.data() + static_cast<std::size_t>(p0 + std::min(l, cnt - 1)) * 3;
    for (int j = 0; j < 3; ++j) qc[j][l] = p[j];
  }
}

// The seed edges (weights w, targets t as doubles) of the cnt lanes of a group from p0.
inline void BoruvkaKdTree::store_seeds(std::uint32_t p0, std::uint32_t cnt, const double* w,
                                       const double* t) {
  for (std::uint32_t l = 0; l < cnt; ++l) {
    cand_w_[p0 + l] = w[l];
    cand_t_[p0 + l] = static_cast<std::uint32_t>(t[l]);
  }
}

#if defined(__AVX2__)
// Squared distances from point p to the four lane queries (qx, qy, qz), summed in dimension
// order with separate roundings (sq_dist_seq per lane).
inline __m256d lanes_sq_dist_avx2(const double* p, __m256d qx, __m256d qy, __m256d qz) {
  const __m256d dx = _mm256_sub_pd(_mm256_broadcast_sd(p), qx);
  const __m256d dy = _mm256_sub_pd(_mm256_broadcast_sd(p + 1), qy);
  const __m256d dz = _mm256_sub_pd(_mm256_broadcast_sd(p + 2), qz);
  __m256d d2 = no_contract_simd(_mm256_mul_pd(dx, dx));
  d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dy, dy)));
  return _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dz, dz)));
}

// Squared distances from the four lane queries to node k's box (box_dist2 per lane).
inline __m256d BoruvkaKdTree::box2_avx2(std::size_t k, __m256d qx, __m256d qy, __m256d qz) const {
  const __m256d zero = _mm256_setzero_pd();
  const double* lo = lo_.data() + k * 3;
  const double* hi = hi_.data() + k * 3;
  const __m256d gx = _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo), qx),
                                                 _mm256_sub_pd(qx, _mm256_broadcast_sd(hi))),
                                   zero);
  const __m256d gy = _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo + 1), qy),
                                                 _mm256_sub_pd(qy, _mm256_broadcast_sd(hi + 1))),
                                   zero);
  const __m256d gz = _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(_mm256_broadcast_sd(lo + 2), qz),
                                                 _mm256_sub_pd(qz, _mm256_broadcast_sd(hi + 2))),
                                   zero);
  __m256d s = no_contract_simd(_mm256_mul_pd(gx, gx));
  s = _mm256_add_pd(s, no_contract_simd(_mm256_mul_pd(gy, gy)));
  return _mm256_add_pd(s, no_contract_simd(_mm256_mul_pd(gz, gz)));
}

// knn_scan with the list held in kB 4-lane registers (4·kB >= kk slots, ascending; bd must
// have 4·kB slots). The merge runs on whole registers: bd[i-1] is the list shifted up one lane
// (a lane permute plus the top lane of the register below; -inf below slot 0). The same
// values as the scalar merge (as KnnTreeSmall::scan_core_avx2).
template <int kB>
inline void BoruvkaKdTree::knn_scan_avx2(const double* q, const Node& nd, std::size_t kk,
                                         double* bd, double& worst) const {
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
inline void BoruvkaKdTree::knn_group_avx2(std::uint32_t p0, std::uint32_t cnt, std::size_t kk,
                                          double* out_r2, std::vector<std::uint32_t>& seen) const {
  const double inf = std::numeric_limits<double>::infinity();
  alignas(32) double qc[3][4];
  lane_points(p0, cnt, qc);
  const __m256d qx = _mm256_load_pd(qc[0]);
  const __m256d qy = _mm256_load_pd(qc[1]);
  const __m256d qz = _mm256_load_pd(qc[2]);
  __m256d v[kL];
  for (int i = 0; i < kL; ++i) {
    v[i] = _mm256_set1_pd(static_cast<std::size_t>(i) < kL - kk ? -inf : inf);
  }
  const __m256d zero = _mm256_setzero_pd();
  auto box2 = [&](std::size_t k) { return box2_avx2(k, qx, qy, qz); };
  auto keep = [&](__m256d b2) {
    return _mm256_movemask_pd(_mm256_cmp_pd(b2, v[kL - 1], _CMP_LE_OQ)) != 0;
  };
  auto scan = [&](const Node& nd) {
    seen.push_back(static_cast<std::uint32_t>(&nd - nodes_.data()));
    const double* p = pts_.data() + static_cast<std::size_t>(nd.begin) * 3;
    for (auto t = nd.begin; t < nd.end; ++t, p += 3) {
      const __m256d d2 = lanes_sq_dist_avx2(p, qx, qy, qz);
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
// lanes_sq_dist_avx2 for the eight AVX-512 lanes.
__attribute__((target("avx512f"))) inline __m512d lanes_sq_dist_avx512(const double* p, __m512d qx,
                                                                       __m512d qy, __m512d qz) {
  const __m512d dx = _mm512_sub_pd(_mm512_set1_pd(p[0]), qx);
  const __m512d dy = _mm512_sub_pd(_mm512_set1_pd(p[1]), qy);
  const __m512d dz = _mm512_sub_pd(_mm512_set1_pd(p[2]), qz);
  __m512d d2 = no_contract_v512(_mm512_mul_pd(dx, dx));
  d2 = _mm512_add_pd(d2, no_contract_v512(_mm512_mul_pd(dy, dy)));
  return _mm512_add_pd(d2, no_contract_v512(_mm512_mul_pd(dz, dz)));
}

// knn_group_avx2 with eight queries, one per AVX-512 lane (the list in kL of the 32 zmm
// registers). Run-time dispatch; written without lambdas, which would not inherit the target.
__attribute__((target("avx512f"))) inline __m512d BoruvkaKdTree::box2_avx512(std::size_t k,
                                                                             __m512d qx, __m512d qy,
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
__attribute__((target("avx512f"))) inline void BoruvkaKdTree::knn_group_avx512(
    std::uint32_t p0, std::uint32_t cnt, std::size_t kk, double* out_r2,
    std::vector<std::uint32_t>& seen) const {
  const double inf = std::numeric_limits<double>::infinity();
  alignas(64) double qc[3][8];
  lane_points(p0, cnt, qc);
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
          const __m512d d2 = lanes_sq_dist_avx512(p, qx, qy, qz);
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
    root = static_cast<std::uint32_t>(pn.left == static_cast<std::int32_t>(c) ? pn.right : pn.left);
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
inline void BoruvkaKdTree::seed_group_avx2(std::uint32_t p0, std::uint32_t cnt,
                                           const std::vector<std::uint32_t>& near,
                                           const double* r2) {
  alignas(32) double qc[3][4], rs[4], cs[4], sp[4];
  lane_points(p0, cnt, qc);
  for (std::uint32_t l = 0; l < 4; ++l) {
    const std::uint32_t s = p0 + std::min(l, cnt - 1);
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
    const __m256d b2 = box2_avx2(leaf, qx, qy, qz);
    const __m256d lb = _mm256_max_pd(vcs, _mm256_set1_pd(nd.min_core));
    const __m256d can =
        _mm256_and_pd(_mm256_cmp_pd(b2, vrs, _CMP_LE_OQ), _mm256_cmp_pd(lb, bw, _CMP_LT_OQ));
    if (_mm256_movemask_pd(can) == 0) continue;
    const double* p = pts_.data() + static_cast<std::size_t>(nd.begin) * 3;
    for (auto t = nd.begin; t < nd.end; ++t, p += 3) {
      const __m256d d2 = lanes_sq_dist_avx2(p, qx, qy, qz);
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
  store_seeds(p0, cnt, ow, ot);
}
#endif

#if defined(DS3D_HDBSCAN_AVX512)
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
__attribute__((target("avx512f"))) inline void BoruvkaKdTree::seed_group_avx512(
    std::uint32_t p0, std::uint32_t cnt, const std::vector<std::uint32_t>& near, const double* r2) {
  alignas(64) double qc[3][8], rs[8], cs[8], sp[8];
  lane_points(p0, cnt, qc);
  for (std::uint32_t l = 0; l < 8; ++l) {
    const std::uint32_t s = p0 + std::min(l, cnt - 1);
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
      const __m512d d2 = lanes_sq_dist_avx512(p, qx, qy, qz);
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
  store_seeds(p0, cnt, ow, ot);
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

}  // namespace ds3d::detail
