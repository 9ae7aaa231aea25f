// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d/cluster/hdbscan.hpp. Each step follows the reference hdbscan 0.8.43 rules
// recorded in tests/data/hdbscan/README.md (numbers in comments refer to its list). Not API.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/detail/kdtree_nd.hpp"
#include "ds3d/detail/mst.hpp"
#include "ds3d/detail/numpy_argsort.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

DS3D_CORE_INLINE void HdbscanParams::validate() const {
  DS3D_CHECK(min_cluster_size >= 2, "ds3d::hdbscan: min_cluster_size must be >= 2 (got ",
             min_cluster_size, ")");
  DS3D_CHECK(min_samples >= 0,
             "ds3d::hdbscan: min_samples must be >= 0, 0 = min_cluster_size (got ", min_samples,
             ")");
  DS3D_CHECK(std::isfinite(cluster_selection_epsilon) && cluster_selection_epsilon >= 0.0,
             "ds3d::hdbscan: cluster_selection_epsilon must be finite and >= 0 (got ",
             cluster_selection_epsilon, ")");
  DS3D_CHECK(max_cluster_size >= 0, "ds3d::hdbscan: max_cluster_size must be >= 0 (got ",
             max_cluster_size, ")");
  DS3D_CHECK(cluster_selection_method == ClusterSelection::kEom ||
                 cluster_selection_method == ClusterSelection::kLeaf,
             "ds3d::hdbscan: cluster_selection_method must be eom or leaf (got ",
             static_cast<int>(cluster_selection_method), ")");
  DS3D_CHECK(algorithm == MstAlgorithm::kAuto || algorithm == MstAlgorithm::kPrims ||
                 algorithm == MstAlgorithm::kBoruvka,
             "ds3d::hdbscan: algorithm must be auto, prims or boruvka (got ",
             static_cast<int>(algorithm), ")");
  (void)detail::resolve_num_threads(num_threads, "ds3d::hdbscan");
}

DS3D_CORE_INLINE std::string to_string(ClusterSelection method) {
  return method == ClusterSelection::kLeaf ? "leaf" : "eom";
}

DS3D_CORE_INLINE std::string to_string(MstAlgorithm algorithm) {
  switch (algorithm) {
    case MstAlgorithm::kPrims:
      return "prims";
    case MstAlgorithm::kBoruvka:
      return "boruvka";
    default:
      return "auto";
  }
}

namespace detail {

/// kAuto switches from Prim to Borůvka at this many points (see docs/hdbscan.md: with the
/// AVX-512 Prim step Prim is faster up to about 4,500 keypoints; with AVX2 only, the two cross
/// near 2,000 to 2,500).
inline constexpr std::size_t kBoruvkaMinPoints = 3000;

/// k of the core distance as the reference computes it: min_samples (or min_cluster_size),
/// clamped to n - 1, raised to 1.
inline int hdbscan_effective_k(const HdbscanParams& p, std::size_t n) {
  std::int64_t k = p.min_samples == 0 ? p.min_cluster_size : p.min_samples;
  k = std::min<std::int64_t>(k, static_cast<std::int64_t>(n) - 1);
  return static_cast<int>(std::max<std::int64_t>(k, 1));
}

/// Union-find for the single-linkage merge (the reference `UnionFind` of `label` numbers each
/// merge n, n+1, ...). Points are joined by size with path halving; each root remembers the
/// linkage node id and size of its component, so find() returns the same node ids as the
/// reference's walk over merge nodes, in fewer steps over half the memory.
class LinkageUnionFind {
 public:
  explicit LinkageUnionFind(std::size_t n)
      : parent_(n), node_(n), size_(n, 1), next_(static_cast<std::int64_t>(n)) {
    std::iota(parent_.begin(), parent_.end(), std::uint32_t{0});
    std::iota(node_.begin(), node_.end(), std::int64_t{0});
  }
  /// Root point of x's component.
  std::uint32_t root(std::uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  /// Linkage node id of the component with root r.
  [[nodiscard]] std::int64_t node(std::uint32_t r) const { return node_[r]; }
  /// Merges the components with roots ra != rb into node next_++; returns its size.
  std::int64_t unite(std::uint32_t ra, std::uint32_t rb) {
    if (size_[ra] < size_[rb]) std::swap(ra, rb);
    parent_[rb] = ra;
    size_[ra] += size_[rb];
    node_[ra] = next_++;
    return size_[ra];
  }

 private:
  std::vector<std::uint32_t> parent_;
  std::vector<std::int64_t> node_;
  std::vector<std::int64_t> size_;
  std::int64_t next_;
};

/// Rule 4: sort the MST by weight and merge with union-find (scipy linkage layout).
inline std::vector<SingleLinkageRow> single_linkage(std::vector<MstEdge>& mst, std::size_t n) {
  std::stable_sort(mst.begin(), mst.end(),
                   [](const MstEdge& a, const MstEdge& b) { return a.weight < b.weight; });
  std::vector<SingleLinkageRow> slt;
  slt.reserve(mst.size());
  LinkageUnionFind uf(n);
  for (const auto& e : mst) {
    const auto ra = uf.root(e.from);
    const auto rb = uf.root(e.to);
    const auto a = uf.node(ra);
    const auto b = uf.node(rb);
    slt.push_back({a, b, e.weight, uf.unite(ra, rb)});
  }
  return slt;
}

/// Prim exactly as the reference's `mst_linkage_core_vector` (unsquared keys, a key replaced only
/// by a strictly smaller one, the first index of the smallest key wins), for
/// HdbscanParams::reference_tie_order: O(n²·D), no SIMD, so equal weights pick the same nodes.
inline std::vector<MstEdge> prim_reference(const double* data, std::size_t n, std::size_t dim,
                                           const std::vector<double>& core) {
  std::vector<MstEdge> edges;
  edges.reserve(n - 1);
  std::vector<double> key(n, std::numeric_limits<double>::infinity());
  std::vector<std::uint32_t> src(n, 0);
  std::vector<char> in_tree(n, 0);
  std::uint32_t cur = 0;
  for (std::size_t step = 1; step < n; ++step) {
    in_tree[cur] = 1;
    double best = std::numeric_limits<double>::max();
    std::uint32_t next = 0;
    for (std::size_t j = 0; j < n; ++j) {
      if (in_tree[j]) continue;
      const double d = std::sqrt(sq_dist_seq(data + cur * dim, data + j * dim, dim));
      const double mr = std::max({d, core[j], core[cur]});
      if (mr < key[j]) {
        key[j] = mr;
        src[j] = cur;
      }
      if (key[j] < best) {
        best = key[j];
        next = static_cast<std::uint32_t>(j);
      }
    }
    edges.push_back({src[next], next, best});
    cur = next;
  }
  return edges;
}

/// Rule 4 with the reference's order under ties (HdbscanParams::reference_tie_order): `mst` is in
/// Prim order from node 0; the reference links each new node to the node added just before it
/// and argsorts the weights with numpy's quicksort.
inline std::vector<SingleLinkageRow> single_linkage_reference_order(std::vector<MstEdge>& mst,
                                                                    std::size_t n) {
  std::vector<double> w(mst.size());
  for (std::size_t i = 0; i < mst.size(); ++i) w[i] = mst[i].weight;
  const auto order = numpy_argsort(w);
  std::vector<MstEdge> sorted;
  sorted.reserve(mst.size());
  std::vector<SingleLinkageRow> slt;
  slt.reserve(mst.size());
  LinkageUnionFind uf(n);
  for (const auto i : order) {
    sorted.push_back(mst[i]);
    const std::uint32_t prev = i == 0 ? 0U : mst[i - 1].to;
    const auto ra = uf.root(prev);
    const auto rb = uf.root(mst[i].to);
    const auto a = uf.node(ra);
    const auto b = uf.node(rb);
    slt.push_back({a, b, mst[i].weight, uf.unite(ra, rb)});
  }
  mst = std::move(sorted);
  return slt;
}

/// Cluster-tree bookkeeping derived from the condensed tree (ids relative to root = n).
struct ClusterTree {
  std::size_t n = 0;
  std::size_t num_clusters = 0;                     // including the root
  std::vector<std::int64_t> parent;                 // per cluster (root: -1)
  std::vector<double> birth;                        // lambda at which the cluster appears (root: 0)
  std::vector<std::int64_t> size;                   // points in the cluster
  std::vector<std::vector<std::int64_t>> children;  // cluster children in row order
  std::vector<double> point_lambda;                 // lambda of each point's own row
  std::vector<std::int64_t> point_parent;           // cluster id of each point's own row
};

/// Rule 5: condensed tree by breadth-first walk from the root, ids in BFS order left first.
inline std::vector<CondensedTreeRow> condense_tree(const std::vector<SingleLinkageRow>& slt,
                                                   std::size_t n, std::int64_t min_cluster_size) {
  std::vector<CondensedTreeRow> rows;
  if (n < 2) return rows;
  rows.reserve(n + 2 * (n / static_cast<std::size_t>(min_cluster_size) + 1));
  const auto nn = static_cast<std::int64_t>(n);
  const std::int64_t root = 2 * nn - 2;
  auto node_size = [&](std::int64_t node) {
    return node < nn ? std::int64_t{1} : slt[static_cast<std::size_t>(node - nn)].size;
  };
  std::vector<std::int64_t> relabel(static_cast<std::size_t>(root + 1), 0);
  relabel[static_cast<std::size_t>(root)] = nn;
  std::int64_t next_label = nn + 1;
  std::vector<std::int64_t> queue{root};
  std::vector<std::int64_t> stack;
  auto fall_out = [&](std::int64_t sub_root, std::int64_t parent, double lambda) {
    stack.assign(1, sub_root);
    while (!stack.empty()) {
      const auto v = stack.back();
      stack.pop_back();
      if (v < nn) {
        rows.push_back({parent, v, lambda, 1});
      } else {
        const auto& r = slt[static_cast<std::size_t>(v - nn)];
        stack.push_back(r.right);
        stack.push_back(r.left);
      }
    }
  };
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const auto node = queue[head];
    if (node < nn) continue;
    const auto& r = slt[static_cast<std::size_t>(node - nn)];
    const double lambda =
        r.distance > 0.0 ? 1.0 / r.distance : std::numeric_limits<double>::infinity();
    const auto left_count = node_size(r.left);
    const auto right_count = node_size(r.right);
    const auto me = relabel[static_cast<std::size_t>(node)];
    const bool left_big = left_count >= min_cluster_size;
    const bool right_big = right_count >= min_cluster_size;
    if (left_big && right_big) {
      relabel[static_cast<std::size_t>(r.left)] = next_label++;
      rows.push_back({me, relabel[static_cast<std::size_t>(r.left)], lambda, left_count});
      relabel[static_cast<std::size_t>(r.right)] = next_label++;
      rows.push_back({me, relabel[static_cast<std::size_t>(r.right)], lambda, right_count});
      queue.push_back(r.left);
      queue.push_back(r.right);
    } else if (!left_big && !right_big) {
      fall_out(r.left, me, lambda);
      fall_out(r.right, me, lambda);
    } else if (!left_big) {
      relabel[static_cast<std::size_t>(r.right)] = me;
      fall_out(r.left, me, lambda);
      queue.push_back(r.right);
    } else {
      relabel[static_cast<std::size_t>(r.left)] = me;
      fall_out(r.right, me, lambda);
      queue.push_back(r.left);
    }
  }
  return rows;
}

inline ClusterTree build_cluster_tree(const std::vector<CondensedTreeRow>& rows, std::size_t n) {
  ClusterTree t;
  t.n = n;
  const auto nn = static_cast<std::int64_t>(n);
  std::int64_t max_id = nn;
  for (const auto& r : rows) max_id = std::max({max_id, r.parent, r.child});
  t.num_clusters = static_cast<std::size_t>(max_id - nn + 1);
  t.parent.assign(t.num_clusters, -1);
  t.birth.assign(t.num_clusters, 0.0);
  t.size.assign(t.num_clusters, 0);
  t.size[0] = nn;
  t.children.assign(t.num_clusters, {});
  t.point_lambda.assign(n, 0.0);
  t.point_parent.assign(n, nn);
  for (const auto& r : rows) {
    if (r.child < nn) {
      t.point_lambda[static_cast<std::size_t>(r.child)] = r.lambda_val;
      t.point_parent[static_cast<std::size_t>(r.child)] = r.parent;
    } else {
      const auto c = static_cast<std::size_t>(r.child - nn);
      t.parent[c] = r.parent;
      t.birth[c] = r.lambda_val;
      t.size[c] = r.child_size;
      t.children[static_cast<std::size_t>(r.parent - nn)].push_back(r.child);
    }
  }
  return t;
}

/// Rules 6-10: stability, EOM / leaf selection, epsilon walk, labels. Returns the selected
/// cluster ids (sorted) and fills the (possibly EOM-modified) stability.
inline std::vector<std::int64_t> select_clusters(const std::vector<CondensedTreeRow>& rows,
                                                 const ClusterTree& t, const HdbscanParams& p,
                                                 std::vector<double>& stability) {
  const auto nn = static_cast<std::int64_t>(t.n);
  const std::size_t nc = t.num_clusters;
  // Rule 6: stability, accumulated in row order.
  stability.assign(nc, 0.0);
  for (const auto& r : rows) {
    const auto pc = static_cast<std::size_t>(r.parent - nn);
    stability[pc] += (r.lambda_val - t.birth[pc]) * static_cast<double>(r.child_size);
  }
  std::vector<char> selected(nc, 0);
  const bool has_split = nc > 1;
  const double eps = p.cluster_selection_epsilon;
  auto birth_distance = [&](std::size_t c) { return 1.0 / t.birth[c]; };
  // Rule 9: walk up from a cluster born below epsilon.
  auto traverse_upwards = [&](std::size_t c) {
    for (;;) {
      const auto par = static_cast<std::size_t>(t.parent[c] - nn);
      if (par == 0) return p.allow_single_cluster ? par : c;
      if (birth_distance(par) > eps) return par;
      c = par;
    }
  };
  auto epsilon_search = [&](const std::vector<std::size_t>& start) {
    std::vector<char> chosen(nc, 0);
    for (const auto c : start) {
      chosen[birth_distance(c) < eps ? traverse_upwards(c) : c] = 1;
    }
    // Drop clusters below a chosen one (ids grow downwards, so parents come first).
    std::vector<char> covered(nc, 0);
    for (std::size_t c = 1; c < nc; ++c) {
      const auto par = static_cast<std::size_t>(t.parent[c] - nn);
      covered[c] = static_cast<char>(covered[par] || chosen[par]);
      if (covered[c]) chosen[c] = 0;
    }
    return chosen;
  };
  if (p.cluster_selection_method == ClusterSelection::kEom) {
    // Rule 7: bottom-up (decreasing id); child sum held in float32 like the reference.
    const std::int64_t max_size = p.max_cluster_size > 0 ? p.max_cluster_size : nn + 1;
    const std::size_t first = p.allow_single_cluster ? 0 : 1;
    for (std::size_t c = nc; c-- > first;) {
      double child_sum = 0.0;
      for (const auto ch : t.children[c]) child_sum += stability[static_cast<std::size_t>(ch - nn)];
      const auto subtree = static_cast<double>(static_cast<float>(child_sum));
      if (subtree > stability[c] || t.size[c] > max_size) {
        selected[c] = 0;
        stability[c] = subtree;
      } else {
        selected[c] = 1;
      }
    }
    // Deselect descendants of selected clusters (top-down).
    std::vector<char> covered(nc, 0);
    for (std::size_t c = 1; c < nc; ++c) {
      const auto par = static_cast<std::size_t>(t.parent[c] - nn);
      covered[c] = static_cast<char>(covered[par] || selected[par]);
      if (covered[c]) selected[c] = 0;
    }
    if (eps != 0.0 && has_split) {
      std::vector<std::size_t> eom;
      for (std::size_t c = 0; c < nc; ++c) {
        if (selected[c]) eom.push_back(c);
      }
      if (eom.size() == 1 && eom[0] == 0) {
        // Only the root: epsilon is skipped (kept only with allow_single_cluster, as selected).
      } else {
        selected = epsilon_search(eom);
      }
    }
  } else {
    // Rule 8: leaves; no split at all gives no cluster.
    std::vector<std::size_t> leaves;
    for (std::size_t c = 1; c < nc; ++c) {
      if (t.children[c].empty()) leaves.push_back(c);
    }
    if (eps != 0.0) {
      selected = epsilon_search(leaves);
    } else {
      for (const auto c : leaves) selected[c] = 1;
    }
  }
  std::vector<std::int64_t> out;
  for (std::size_t c = 0; c < nc; ++c) {
    if (selected[c]) out.push_back(static_cast<std::int64_t>(c) + nn);
  }
  return out;
}

/// Rules 10-12 and persistence from a finished condensed tree.
inline void finish_result(HdbscanResult& res, const HdbscanParams& p, std::size_t n) {
  const auto nn = static_cast<std::int64_t>(n);
  const ClusterTree t = build_cluster_tree(res.condensed_tree, n);
  const std::size_t nc = t.num_clusters;
  std::vector<double> stability;
  const auto clusters = select_clusters(res.condensed_tree, t, p, stability);
  // Direct-children death and whole-subtree maximum lambda.
  std::vector<double> death(nc, 0.0);
  for (const auto& r : res.condensed_tree) {
    auto& d = death[static_cast<std::size_t>(r.parent - nn)];
    d = std::max(d, r.lambda_val);
  }
  std::vector<double> lmax = death;
  for (std::size_t c = nc; c-- > 1;) {
    auto& up = lmax[static_cast<std::size_t>(t.parent[c] - nn)];
    up = std::max(up, lmax[c]);
  }
  // Rule 10: labels through the nearest selected ancestor.
  std::vector<std::int32_t> label_of(nc, -1);
  for (std::size_t i = 0; i < clusters.size(); ++i) {
    label_of[static_cast<std::size_t>(clusters[i] - nn)] = static_cast<std::int32_t>(i);
  }
  std::vector<std::int64_t> owner(nc, -1);  // selected ancestor-or-self
  for (std::size_t c = 0; c < nc; ++c) {
    if (label_of[c] >= 0) {
      owner[c] = static_cast<std::int64_t>(c);
    } else if (c > 0) {
      owner[c] = owner[static_cast<std::size_t>(t.parent[c] - nn)];
    }
  }
  const bool root_single = clusters.size() == 1 && clusters[0] == nn;
  const double eps = p.cluster_selection_epsilon;
  res.labels.assign(n, -1);
  res.probabilities.assign(n, 0.0);
  res.outlier_scores.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const auto pc = static_cast<std::size_t>(t.point_parent[i] - nn);
    const double lam = t.point_lambda[i];
    const auto own = owner[pc];
    if (own == 0) {
      const bool keep = root_single && p.allow_single_cluster &&
                        (eps != 0.0 ? lam >= 1.0 / eps : lam >= death[0]);
      if (keep) res.labels[i] = 0;
    } else if (own > 0) {
      res.labels[i] = label_of[static_cast<std::size_t>(own)];
    }
    // Rule 11: probability against the labelled cluster's direct death lambda.
    if (res.labels[i] >= 0) {
      const double dth = death[static_cast<std::size_t>(own)];
      res.probabilities[i] = (dth == 0.0 || !std::isfinite(lam)) ? 1.0 : std::min(lam, dth) / dth;
    }
    // Rule 12: GLOSH against the parent's subtree maximum (inf/inf gives NaN as in the reference).
    const double lm = lmax[pc];
    res.outlier_scores[i] = (lm == 0.0 || !std::isfinite(lam)) ? 0.0 : (lm - lam) / lm;
  }
  // Persistence: stability / (members × max lambda of the whole tree), 1 when undefined.
  double max_lambda = 0.0;
  for (const auto& r : res.condensed_tree) max_lambda = std::max(max_lambda, r.lambda_val);
  // Clusters that received points (the root selected under allow_single_cluster may receive
  // none, rule 10; it still has a persistence entry, as in the reference).
  res.num_clusters = 0;
  for (const auto l : res.labels) res.num_clusters = std::max(res.num_clusters, l + 1);
  res.selected_clusters = clusters;
  res.cluster_persistence.assign(clusters.size(), 1.0);
  std::vector<std::int64_t> members(clusters.size(), 0);
  for (const auto l : res.labels) {
    if (l >= 0) ++members[static_cast<std::size_t>(l)];
  }
  for (std::size_t i = 0; i < clusters.size(); ++i) {
    if (std::isfinite(max_lambda) && max_lambda != 0.0 && members[i] > 0) {
      res.cluster_persistence[i] = stability[static_cast<std::size_t>(clusters[i] - nn)] /
                                   (static_cast<double>(members[i]) * max_lambda);
    }
  }
}

/// Everything after the core distances and the MST.
inline void hdbscan_from_mst(HdbscanResult& res, std::vector<MstEdge> mst, const HdbscanParams& p,
                             std::size_t n, bool prim_order = false) {
  res.single_linkage_tree = prim_order && p.reference_tie_order
                                ? single_linkage_reference_order(mst, n)
                                : single_linkage(mst, n);
  res.min_spanning_tree = std::move(mst);
  res.condensed_tree = condense_tree(res.single_linkage_tree, n, p.min_cluster_size);
  finish_result(res, p, n);
}

/// Power-of-two exponent e such that the coordinates divided by 2^e keep every squared distance
/// finite and normal: 0 (no rescaling, so ordinary data run untouched) while the largest
/// |coordinate| lies in [2^-200, 2^200], else the exponent that brings it into [1, 2). Scaling by
/// 2^-e is exact and every step of the algorithm is scale invariant, so the result is the one
/// exact arithmetic would give. Throws when the point set's diameter is not representable.
inline int hdbscan_range_exponent(const std::vector<double>& data, std::size_t n, std::size_t dim) {
  double big = 0.0;
  std::size_t arg = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (std::abs(data[i]) > big) {
      big = std::abs(data[i]);
      arg = i;
    }
  }
  if (big == 0.0 || (big <= 0x1p200 && big >= 0x1p-200)) return 0;
  const int e = std::ilogb(big);
  double diam2 = 0.0;  // squared diameter of the bounding box, in units of 2^e
  for (std::size_t j = 0; j < dim; ++j) {
    double lo = std::numeric_limits<double>::infinity();
    double hi = -lo;
    for (std::size_t i = 0; i < n; ++i) {
      lo = std::min(lo, std::ldexp(data[i * dim + j], -e));
      hi = std::max(hi, std::ldexp(data[i * dim + j], -e));
    }
    diam2 += (hi - lo) * (hi - lo);
  }
  // Twice the diameter must stay finite so that rounded distances near it cannot overflow.
  DS3D_CHECK(std::isfinite(std::ldexp(std::sqrt(diam2), e + 1)), "ds3d::hdbscan: points row ",
             arg / dim, " column ", arg % dim, ": coordinate ", data[arg],
             " beyond the supported range (the points' bounding-box diameter must stay below ",
             std::numeric_limits<double>::max() / 2, ")");
  return e;
}

/// Maps a result computed on coordinates divided by 2^e back to the caller's units: distances
/// times 2^e, lambdas (1 / distance) times 2^-e; probabilities, scores and persistence are ratios.
inline void hdbscan_unscale(HdbscanResult& res, int e) {
  for (auto& c : res.core_distances) c = std::ldexp(c, e);
  for (auto& m : res.min_spanning_tree) m.weight = std::ldexp(m.weight, e);
  for (auto& s : res.single_linkage_tree) s.distance = std::ldexp(s.distance, e);
  for (auto& r : res.condensed_tree) r.lambda_val = std::ldexp(r.lambda_val, -e);
}

/// cluster_selection_epsilon in units of 2^e; a positive epsilon stays positive.
inline double hdbscan_scaled_epsilon(double eps, int e) {
  if (eps == 0.0) return eps;
  return std::max(std::ldexp(eps, -e), std::numeric_limits<double>::denorm_min());
}

/// The MST must have n - 1 finite edges between distinct points; anything else is a bug or an
/// arithmetic overflow that would corrupt the tree steps, so it is reported instead.
inline void hdbscan_check_mst(const std::vector<MstEdge>& mst, std::size_t n) {
  DS3D_CHECK_AS(NumericalError, mst.size() + 1 == n, "ds3d::hdbscan: minimum spanning tree has ",
                mst.size(), " edges for ", n, " points");
  for (const auto& e : mst) {
    DS3D_CHECK_AS(NumericalError,
                  std::isfinite(e.weight) && e.from < n && e.to < n && e.from != e.to,
                  "ds3d::hdbscan: invalid minimum spanning tree edge ", e.from, " - ", e.to,
                  " (weight ", e.weight, ")");
  }
}

inline HdbscanResult hdbscan_trivial(std::size_t n) {
  HdbscanResult res;
  res.labels.assign(n, -1);
  res.probabilities.assign(n, 0.0);
  res.outlier_scores.assign(n, 0.0);
  res.core_distances.assign(n, 0.0);
  return res;
}

}  // namespace detail

DS3D_CORE_INLINE HdbscanResult hdbscan(Eigen::Ref<const RowMatrixXd> points,
                                       const HdbscanParams& params,
                                       const std::vector<double>& scale) {
  params.validate();
  const auto n = static_cast<std::size_t>(points.rows());
  const auto dim = static_cast<std::size_t>(points.cols());
  DS3D_CHECK(dim >= 1 || n == 0, "ds3d::hdbscan: points must have at least 1 column (got ", dim,
             ")");
  DS3D_CHECK(scale.empty() || scale.size() == dim, "ds3d::hdbscan: scale must be empty or have ",
             dim, " entries, one per column (got ", scale.size(), ")");
  for (std::size_t j = 0; j < scale.size(); ++j) {
    DS3D_CHECK(std::isfinite(scale[j]) && scale[j] > 0.0, "ds3d::hdbscan: scale[", j,
               "] must be finite and > 0 (got ", scale[j], ")");
  }
  DS3D_CHECK(n < std::numeric_limits<std::uint32_t>::max() / 2,
             "ds3d::hdbscan: too many points (got ", n, ")");
  std::vector<double> data(n * dim);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < dim; ++j) {
      const double v = points(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
      DS3D_CHECK(std::isfinite(v), "ds3d::hdbscan: points row ", i, " column ", j,
                 " is not finite (got ", v, ")");
      data[i * dim + j] = scale.empty() ? v : v * scale[j];
      DS3D_CHECK(std::isfinite(data[i * dim + j]), "ds3d::hdbscan: points row ", i, " column ", j,
                 " times scale[", j, "] overflows (got ", v, " * ", scale[j], ")");
    }
  }
  if (n < 2) return detail::hdbscan_trivial(n);
  const int range_exp = detail::hdbscan_range_exponent(data, n, dim);
  HdbscanParams p = params;
  if (range_exp != 0) {
    for (auto& v : data) v = std::ldexp(v, -range_exp);
    p.cluster_selection_epsilon =
        detail::hdbscan_scaled_epsilon(p.cluster_selection_epsilon, range_exp);
  }
  HdbscanResult res;
  const int threads = detail::resolve_num_threads(params.num_threads, "ds3d::hdbscan");
  const int k = detail::hdbscan_effective_k(params, n);
  res.min_samples_effective = k;
  const detail::DenseRowsNd ds{data.data(), n, dim};
  const bool use_boruvka =
      params.algorithm == MstAlgorithm::kBoruvka ||
      (params.algorithm == MstAlgorithm::kAuto && n >= detail::kBoruvkaMinPoints && dim <= 8);
  std::vector<MstEdge> mst;
  if (!use_boruvka && params.reference_tie_order) {
    res.core_distances = detail::knn_core_distances(ds, static_cast<std::size_t>(k), threads);
    mst = detail::prim_reference(data.data(), n, dim, res.core_distances);
  } else if (use_boruvka) {
    mst = detail::boruvka_kdtree(data.data(), n, dim, static_cast<std::size_t>(k), threads,
                                 res.core_distances);
  } else {
    const auto kk = static_cast<std::size_t>(k) + 1;
    res.core_distances = detail::knn_lane_width(dim, kk, detail::KnnLanes::kAuto) > 0
                             ? detail::boruvka_core_distances(data.data(), n, dim,
                                                              static_cast<std::size_t>(k), threads)
                             : detail::knn_core_distances(ds, static_cast<std::size_t>(k), threads);
    mst = detail::prim_dense(data.data(), n, dim, res.core_distances);
  }
  detail::hdbscan_check_mst(mst, n);
  detail::hdbscan_from_mst(res, std::move(mst), p, n, !use_boruvka);
  if (range_exp != 0) detail::hdbscan_unscale(res, range_exp);
  return res;
}

DS3D_CORE_INLINE HdbscanResult hdbscan_precomputed(Eigen::Ref<const RowMatrixXd> distances,
                                                   const HdbscanParams& params) {
  params.validate();
  const auto n = static_cast<std::size_t>(distances.rows());
  DS3D_CHECK(distances.cols() == distances.rows(),
             "ds3d::hdbscan_precomputed: distances must be square (got ", distances.rows(), " x ",
             distances.cols(), ")");
  std::vector<double> d(n * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      const double v = distances(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
      DS3D_CHECK(std::isfinite(v) && v >= 0.0, "ds3d::hdbscan_precomputed: distances(", i, ", ", j,
                 ") must be finite and >= 0 (got ", v, ")");
      DS3D_CHECK(i != j || v == 0.0, "ds3d::hdbscan_precomputed: distances(", i, ", ", i,
                 ") must be 0 (got ", v, ")");
      DS3D_CHECK(j >= i || v == d[j * n + i],
                 "ds3d::hdbscan_precomputed: distances must be symmetric (", i, ", ", j, ") = ", v,
                 " but (", j, ", ", i, ") = ", d[j * n + i]);
      d[i * n + j] = v;
    }
  }
  if (n < 2) return detail::hdbscan_trivial(n);
  HdbscanResult res;
  const int k = detail::hdbscan_effective_k(params, n);
  res.min_samples_effective = k;
  res.core_distances.resize(n);
  std::vector<double> row(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::copy_n(d.data() + i * n, n, row.data());
    std::nth_element(row.begin(), row.begin() + k, row.end());
    res.core_distances[i] = row[static_cast<std::size_t>(k)];
  }
  std::vector<MstEdge> mst = detail::prim_precomputed(d.data(), n, res.core_distances);
  detail::hdbscan_from_mst(res, std::move(mst), params, n);
  return res;
}

}  // namespace ds3d
