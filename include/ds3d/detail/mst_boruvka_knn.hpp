// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// BoruvkaKdTree's first pass: every point's core distance and its seed edge (the cheapest
// edge into its core ball), one walk per query. Out-of-class members of mst_boruvka.hpp. Not API:
// see ds3d/detail/mst.hpp.

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

// Squared distances from q to the kLeafSize tree positions from b into buf (lanes past a
// node's end read other points or the zero padding; callers mask them), each summed in
// dimension order with separate roundings, i.e. bitwise sq_dist_seq. Returns the bit mask of
// the lanes with buf[t] < r2 (kLe = false) or buf[t] <= r2 (kLe = true).
template <bool kLe>
inline std::uint32_t BoruvkaKdTree::block_dist2(const double* q, std::size_t b, double r2,
                                                double* buf) const {
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
      const __m256d hit = kLe ? _mm256_cmp_pd(d2, w, _CMP_LE_OQ) : _mm256_cmp_pd(d2, w, _CMP_LT_OQ);
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
inline void BoruvkaKdTree::knn_scan(const double* q, const Node& nd, std::size_t kk, double* bd,
                                    double& worst) const {
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
inline void BoruvkaKdTree::walk_from_leaf(const double* q, std::uint32_t leaf, Keep&& keep,
                                          Visit&& visit) const {
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
inline void BoruvkaKdTree::knn_query(std::uint32_t s, std::uint32_t leaf, std::size_t kk,
                                     double* bd, std::vector<std::uint32_t>& seen,
                                     std::vector<std::uint32_t>& mark, std::uint32_t stamp) const {
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
inline void BoruvkaKdTree::seed_query(std::uint32_t s, const std::uint32_t* near,
                                      std::size_t num_near, double rs, double& best_w,
                                      std::uint32_t& best_t) const {
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
        const auto len = static_cast<std::uint32_t>(std::min<std::size_t>(kLeafSize, nd.end - bb));
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
inline std::uint32_t BoruvkaKdTree::group_start(std::uint32_t p0, std::uint32_t cnt) const {
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
inline void BoruvkaKdTree::knn_and_seeds(std::size_t kk) {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> r2(n_);
  // Query units: groups of `width` consecutive tree positions searched in one walk, one per
  // SIMD lane (knn_group_avx512: 8, knn_group_avx2: 4; D = 3, kk <= 16, see KnnLanes), else
  // leaves (per-query walks). unit_begin[u] is the first tree position of unit u; near[u]
  // lists, in tree order, the leaves scanned for its queries.
  const std::size_t width = knn_lane_width(dim_, kk, lanes_);  // 0 = per-query search
  const std::vector<std::uint32_t> unit_begin = query_units(width);
  const std::size_t units = unit_begin.size() - 1;
  std::vector<std::vector<std::uint32_t>> near(seeds_ || width == 0 ? units : 0);
  cand_w_.assign(n_, inf);
  cand_t_.assign(n_, 0U);
  const std::size_t chunks = std::size_t{16} * static_cast<std::size_t>(std::max(1, threads_));
  parallel_chunks(units, chunks, threads_, [&](std::size_t b, std::size_t e, std::size_t) {
    if (width > 0) {
      core_groups(b, e, width, kk, unit_begin, r2, near);
    } else {
      core_leaves(b, e, kk, r2, near);
    }
  });
  if (!seeds_) return;
  set_min_core();
  parallel_chunks(units, chunks, threads_, [&](std::size_t b, std::size_t e, std::size_t) {
    seed_units(b, e, width, unit_begin, near, r2);
  });
}

// First tree position of each query unit of knn_and_seeds (groups of `width` positions, or the
// leaves when width = 0), then n_.
inline std::vector<std::uint32_t> BoruvkaKdTree::query_units(std::size_t width) const {
  std::vector<std::uint32_t> unit_begin;
  if (width > 0) {
    unit_begin.reserve(n_ / width + 2);
    for (std::size_t p = 0; p < n_; p += width) {
      unit_begin.push_back(static_cast<std::uint32_t>(p));
    }
  } else {
    for (const auto leaf : leaves_) unit_begin.push_back(nodes_[leaf].begin);
  }
  unit_begin.push_back(static_cast<std::uint32_t>(n_));
  return unit_begin;
}

// Pass 1 over the lane groups b .. e - 1 (width 8 or 4): squared core radii into r2, core
// distances, and (with seeds) each group's scanned leaves in near[u], sorted.
inline void BoruvkaKdTree::core_groups(std::size_t b, std::size_t e, std::size_t width,
                                       std::size_t kk, const std::vector<std::uint32_t>& unit_begin,
                                       std::vector<double>& r2,
                                       std::vector<std::vector<std::uint32_t>>& near) {
  std::vector<std::uint32_t> scratch;  // scanned leaves when no seeds are wanted
  for (std::size_t u = b; u < e; ++u) {
    const auto p0 = unit_begin[u];
    const auto cnt = unit_begin[u + 1] - p0;
    double* out = r2.data() + p0;
    auto& seen = seeds_ ? near[u] : scratch;
    knn_group(width, p0, cnt, kk, out, seen);
    for (auto s = p0; s < p0 + cnt; ++s) core_[s] = std::sqrt(r2[s]);
    if (!seeds_) {
      scratch.clear();
      continue;
    }
    std::sort(near[u].begin(), near[u].end());  // leaf ids in preorder = tree order
  }
}

// Pass 1 over the leaves b .. e - 1, one walk per query (knn_query).
inline void BoruvkaKdTree::core_leaves(std::size_t b, std::size_t e, std::size_t kk,
                                       std::vector<double>& r2,
                                       std::vector<std::vector<std::uint32_t>>& near) {
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
}

// Smallest core distance below every node (bottom-up over the preorder array).
inline void BoruvkaKdTree::set_min_core() {
  const double inf = std::numeric_limits<double>::infinity();
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
}

// Pass 2 over the query units b .. e - 1: the seed edge of each of their positions.
inline void BoruvkaKdTree::seed_units(std::size_t b, std::size_t e,
                                      [[maybe_unused]] std::size_t width,
                                      const std::vector<std::uint32_t>& unit_begin,
                                      const std::vector<std::vector<std::uint32_t>>& near,
                                      const std::vector<double>& r2) {
  const double inf = std::numeric_limits<double>::infinity();
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
}

}  // namespace ds3d::detail
