// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// KD-tree Borůvka MST of the mutual-reachability graph: the tree, its rounds and the
// per-point edge search. Its core-distance and seed passes are in mst_boruvka_knn.hpp, their SIMD
// kernels in mst_boruvka_simd.hpp. Not API: see ds3d/detail/mst.hpp.

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

#include "ds3d/detail/mst.hpp"

namespace ds3d::detail {

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

  // Core distances and seed edges (mst_boruvka_knn.hpp).
  template <bool kLe>
  std::uint32_t block_dist2(const double* q, std::size_t b, double r2, double* buf) const;
  void knn_scan(const double* q, const Node& nd, std::size_t kk, double* bd, double& worst) const;
  template <class Keep, class Visit>
  void walk_from_leaf(const double* q, std::uint32_t leaf, Keep&& keep, Visit&& visit) const;
  void knn_query(std::uint32_t s, std::uint32_t leaf, std::size_t kk, double* bd,
                 std::vector<std::uint32_t>& seen, std::vector<std::uint32_t>& mark,
                 std::uint32_t stamp) const;
  void seed_query(std::uint32_t s, const std::uint32_t* near, std::size_t num_near, double rs,
                  double& best_w, std::uint32_t& best_t) const;
  [[nodiscard]] std::uint32_t group_start(std::uint32_t p0, std::uint32_t cnt) const;
  void knn_and_seeds(std::size_t kk);
  [[nodiscard]] std::vector<std::uint32_t> query_units(std::size_t width) const;
  void core_groups(std::size_t b, std::size_t e, std::size_t width, std::size_t kk,
                   const std::vector<std::uint32_t>& unit_begin, std::vector<double>& r2,
                   std::vector<std::vector<std::uint32_t>>& near);
  void core_leaves(std::size_t b, std::size_t e, std::size_t kk, std::vector<double>& r2,
                   std::vector<std::vector<std::uint32_t>>& near);
  void set_min_core();
  void seed_units(std::size_t b, std::size_t e, std::size_t width,
                  const std::vector<std::uint32_t>& unit_begin,
                  const std::vector<std::vector<std::uint32_t>>& near,
                  const std::vector<double>& r2);

  // The same passes with one query per SIMD lane (mst_boruvka_simd.hpp).
  void knn_group(std::size_t width, std::uint32_t p0, std::uint32_t cnt, std::size_t kk,
                 double* out_r2, std::vector<std::uint32_t>& seen) const;
  template <std::uint32_t kW>
  void lane_points(std::uint32_t p0, std::uint32_t cnt, double (&qc)[3][kW]) const;
  void store_seeds(std::uint32_t p0, std::uint32_t cnt, const double* w, const double* t);
#if defined(__AVX2__)
  template <int kB>
  void knn_scan_avx2(const double* q, const Node& nd, std::size_t kk, double* bd,
                     double& worst) const;
  template <int kL>
  void knn_group_avx2(std::uint32_t p0, std::uint32_t cnt, std::size_t kk, double* out_r2,
                      std::vector<std::uint32_t>& seen) const;
  void seed_group_avx2(std::uint32_t p0, std::uint32_t cnt, const std::vector<std::uint32_t>& near,
                       const double* r2);
  [[nodiscard]] __m256d box2_avx2(std::size_t k, __m256d qx, __m256d qy, __m256d qz) const;
#endif
#if defined(DS3D_HDBSCAN_AVX512)
  [[nodiscard]] __attribute__((target("avx512f"))) __m512d box2_avx512(std::size_t k, __m512d qx,
                                                                       __m512d qy,
                                                                       __m512d qz) const;
  template <int kL>
  __attribute__((target("avx512f"))) void knn_group_avx512(std::uint32_t p0, std::uint32_t cnt,
                                                           std::size_t kk, double* out_r2,
                                                           std::vector<std::uint32_t>& seen) const;
  __attribute__((target("avx512f"))) void seed_group_avx512(std::uint32_t p0, std::uint32_t cnt,
                                                            const std::vector<std::uint32_t>& near,
                                                            const double* r2);
#endif

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
                                           std::vector<double>& core, KnnLanes lanes) {
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
                                                  KnnLanes lanes) {
  if (n < 2) return std::vector<double>(n, 0.0);
  return BoruvkaKdTree(data, n, dim, k, num_threads, lanes, false).core_distances();
}

}  // namespace ds3d::detail

// Last: the out-of-class member definitions (each includes this header first).
#include "ds3d/detail/mst_boruvka_knn.hpp"
#include "ds3d/detail/mst_boruvka_simd.hpp"
