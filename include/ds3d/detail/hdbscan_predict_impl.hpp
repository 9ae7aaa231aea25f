// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d/cluster/hdbscan_predict.hpp, following the reference hdbscan 0.8.43
// prediction rules listed in docs/hdbscan.md ("Prediction"). Not API.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <utility>
#include <vector>

#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/cluster/hdbscan_predict.hpp"
#include "ds3d/detail/kdtree_nd.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// Everything the queries read; cluster ids are stored relative to the root (id - n).
struct HdbscanPredictor::State {
  std::size_t n = 0;
  std::size_t dim = 0;
  int k = 1;                 // neighbourhood size (min_samples, clamped to n)
  std::vector<double> data;  // n × dim, row-major
  detail::DenseRowsNd rows;  // view of data
  std::unique_ptr<detail::KdTreeNd<-1>> tree;
  std::vector<double> core;                  // distance to the k-th nearest point, itself included
  std::vector<std::int64_t> point_parent;    // cluster of each point's own row
  std::vector<double> point_lambda;          // lambda of each point's own row
  std::vector<std::int64_t> cluster_parent;  // per cluster; -1 for the root
  std::vector<double> cluster_birth;         // lambda of the cluster's row (root: 0)
  std::vector<double> leaf_max_lambda;       // max lambda over the cluster's direct rows
  std::vector<std::int32_t> cluster_label;   // label of the selected ancestor-or-self, or -1
  std::vector<double> label_max_lambda;      // max lambda of that selected cluster
  std::vector<std::int64_t> selected;        // selected clusters, in label order
  std::vector<std::vector<std::uint32_t>> exemplars;  // per label
  bool has_split = false;                             // the condensed tree has cluster rows
};

namespace detail {

/// Sorted (distance, index) neighbour list of one query point.
struct PredictNeighbors {
  std::vector<std::uint32_t> idx;
  std::vector<double> dist;
};

/// The m = min(2k, n) nearest fitted points of q, by exact distance then index (the reference
/// queries 2 · min_samples neighbours).
inline PredictNeighbors predict_neighbors(const HdbscanPredictor::State& s, const double* q) {
  const std::size_t m = std::min(2 * static_cast<std::size_t>(s.k), s.n);
  PredictNeighbors nb;
  nb.idx.resize(m);
  std::vector<double> d2(m);
  const std::size_t found = s.tree->knnSearch(q, m, nb.idx.data(), d2.data());
  nb.idx.resize(found);
  std::vector<std::pair<double, std::uint32_t>> order(found);
  for (std::size_t t = 0; t < found; ++t) {
    order[t] = {sq_dist_seq(q, s.data.data() + nb.idx[t] * s.dim, s.dim), nb.idx[t]};
  }
  std::sort(order.begin(), order.end());
  nb.dist.resize(found);
  for (std::size_t t = 0; t < found; ++t) {
    nb.dist[t] = std::sqrt(order[t].first);
    nb.idx[t] = order[t].second;
  }
  return nb;
}

/// Nearest neighbour by mutual reachability and the lambda of that connection (reference
/// `_find_neighbor_and_lambda`): the query's own core distance is its k-th neighbour distance.
inline std::pair<std::uint32_t, double> predict_neighbor_lambda(const HdbscanPredictor::State& s,
                                                                const PredictNeighbors& nb) {
  const double own_core = nb.dist[std::min(static_cast<std::size_t>(s.k), nb.dist.size() - 1)];
  std::size_t best = 0;
  double best_mr = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < nb.idx.size(); ++t) {
    const double mr = std::max({s.core[nb.idx[t]], own_core, nb.dist[t]});
    if (mr < best_mr) {
      best_mr = mr;
      best = t;
    }
  }
  const double lambda = best_mr > 0.0 ? 1.0 / best_mr : std::numeric_limits<double>::max();
  return {nb.idx[best], lambda};
}

/// Lambda at which cluster c merges with the branch of point cluster pc (reference
/// `merge_height`): the birth of the lowest common ancestor's child when both walk up, else the
/// point's own lambda (one cluster lies below the other).
inline double merge_height(const HdbscanPredictor::State& s, std::int64_t pc, double point_lambda,
                           std::int64_t c) {
  bool left_moved = false;
  bool right_moved = false;
  std::int64_t last = pc;
  while (pc != c) {
    if (pc > c) {
      left_moved = true;
      last = pc;
      pc = s.cluster_parent[static_cast<std::size_t>(pc)];
    } else {
      right_moved = true;
      last = c;
      c = s.cluster_parent[static_cast<std::size_t>(c)];
    }
  }
  return left_moved && right_moved ? s.cluster_birth[static_cast<std::size_t>(last)] : point_lambda;
}

/// Per-label distance term (reference `dist_membership_vector`): normalised inverse distance to
/// the nearest exemplar of each cluster.
inline void distance_memberships(const HdbscanPredictor::State& s, const double* q, double* out) {
  const std::size_t nl = s.exemplars.size();
  double sum = 0.0;
  for (std::size_t l = 0; l < nl; ++l) {
    double best = std::numeric_limits<double>::max();
    for (const auto e : s.exemplars[l]) {
      best = std::min(best, std::sqrt(sq_dist_seq(q, s.data.data() + e * s.dim, s.dim)));
    }
    out[l] =
        best != 0.0 ? 1.0 / best : std::numeric_limits<double>::max() / static_cast<double>(nl);
    sum += out[l];
  }
  for (std::size_t l = 0; l < nl; ++l) out[l] /= sum;
}

/// Probability of being in some cluster (reference `prob_in_some_cluster` and its all-points
/// form): highest merge height over the nearest cluster's maximum lambda.
inline double prob_in_some_cluster(const HdbscanPredictor::State& s, std::int64_t pc, double lambda,
                                   double eps) {
  double best_h = -1.0;
  std::size_t best = 0;
  for (std::size_t l = 0; l < s.selected.size(); ++l) {
    const double h = merge_height(s, pc, lambda, s.selected[l]);
    if (h > best_h) {
      best_h = h;
      best = l;
    }
  }
  const double ml =
      std::max(lambda, s.leaf_max_lambda[static_cast<std::size_t>(s.selected[best])]) + eps;
  return best_h / ml;
}

/// Scales a row to sum 1 (an all-zero or non-finite row stays all zero: no NaN leaves).
inline void normalise_row(double* v, std::size_t len) {
  double sum = 0.0;
  for (std::size_t l = 0; l < len; ++l) sum += v[l];
  for (std::size_t l = 0; l < len; ++l) {
    v[l] = sum > 0.0 && std::isfinite(sum) ? v[l] / sum : 0.0;
  }
}

/// Membership row of a new point (reference `membership_vector`).
inline void query_membership(const HdbscanPredictor::State& s, const double* q, double* out) {
  const std::size_t nl = s.selected.size();
  const auto nb = predict_neighbors(s, q);
  auto [nearest, lambda] = predict_neighbor_lambda(s, nb);
  const std::int64_t pc = s.point_parent[nearest];
  lambda = std::min(lambda, s.point_lambda[nearest]);
  std::vector<double> dist_vec(nl);
  distance_memberships(s, q, dist_vec.data());
  // Outlier term: softmax of max_lambda / (max_lambda - height), a denominator <= 0 taken as
  // 1e-8. The reference passes lambda through a float32 argument here, so the height uses the
  // rounded value.
  const double ml = s.leaf_max_lambda[static_cast<std::size_t>(pc)];
  const auto lambda32 = static_cast<double>(static_cast<float>(lambda));
  std::vector<double> score(nl);
  double top = -std::numeric_limits<double>::infinity();
  for (std::size_t l = 0; l < nl; ++l) {
    const double den = ml - merge_height(s, pc, lambda32, s.selected[l]);
    score[l] = ml / (den > 0.0 ? den : 1e-8);
    top = std::max(top, score[l]);
  }
  for (std::size_t l = 0; l < nl; ++l) score[l] = std::exp(score[l] - top);
  normalise_row(score.data(), nl);
  // The reference weighs the two terms as sqrt(distance term) · (outlier term)².
  for (std::size_t l = 0; l < nl; ++l) out[l] = std::sqrt(dist_vec[l]) * score[l] * score[l];
  normalise_row(out, nl);
  const double p = prob_in_some_cluster(s, pc, lambda, 1e-8);
  for (std::size_t l = 0; l < nl; ++l) out[l] = std::isfinite(p) ? out[l] * p : 0.0;
}

inline void check_query(const HdbscanPredictor::State& s, const Eigen::Ref<const RowMatrixXd>& q,
                        const char* fn) {
  DS3D_CHECK(static_cast<std::size_t>(q.cols()) == s.dim || q.rows() == 0, fn, ": query must have ",
             s.dim, " columns like the fitted points (got ", q.cols(), ")");
  for (Eigen::Index i = 0; i < q.rows(); ++i) {
    for (Eigen::Index j = 0; j < q.cols(); ++j) {
      DS3D_CHECK(std::isfinite(q(i, j)), fn, ": query row ", i, " column ", j,
                 " is not finite (got ", q(i, j), ")");
    }
  }
}

/// Row-major copy of row i of q (an Eigen::Ref may have any stride).
inline std::vector<double> query_row(const Eigen::Ref<const RowMatrixXd>& q, Eigen::Index i) {
  std::vector<double> row(static_cast<std::size_t>(q.cols()));
  for (Eigen::Index j = 0; j < q.cols(); ++j) row[static_cast<std::size_t>(j)] = q(i, j);
  return row;
}

}  // namespace detail

inline std::size_t HdbscanPredictor::size() const noexcept { return state_->n; }
inline std::size_t HdbscanPredictor::dim() const noexcept { return state_->dim; }
inline int HdbscanPredictor::num_labels() const noexcept {
  return static_cast<int>(state_->selected.size());
}
inline int HdbscanPredictor::min_samples() const noexcept { return state_->k; }
inline const std::vector<double>& HdbscanPredictor::core_distances() const noexcept {
  return state_->core;
}

inline const std::vector<std::uint32_t>& HdbscanPredictor::exemplars(int label) const {
  DS3D_CHECK(label >= 0 && label < num_labels(),
             "ds3d::HdbscanPredictor::exemplars: label must be "
             "in [0, ",
             num_labels(), ") (got ", label, ")");
  return state_->exemplars[static_cast<std::size_t>(label)];
}

inline HdbscanPrediction HdbscanPredictor::approximate_predict(
    Eigen::Ref<const RowMatrixXd> query) const {
  const State& s = *state_;
  detail::check_query(s, query, "ds3d::HdbscanPredictor::approximate_predict");
  const auto m = static_cast<std::size_t>(query.rows());
  HdbscanPrediction out;
  out.labels.assign(m, -1);
  out.probabilities.assign(m, 0.0);
  if (!s.has_split) return out;
  for (std::size_t i = 0; i < m; ++i) {
    const auto q = detail::query_row(query, static_cast<Eigen::Index>(i));
    const auto nb = detail::predict_neighbors(s, q.data());
    const auto [nearest, lambda] = detail::predict_neighbor_lambda(s, nb);
    std::int64_t c = s.point_parent[nearest];
    if (s.point_lambda[nearest] > lambda) {
      // Hang the point as high as its lambda says: leave every cluster born at or after it.
      while (c > 0 && s.cluster_birth[static_cast<std::size_t>(c)] >= lambda) {
        c = s.cluster_parent[static_cast<std::size_t>(c)];
      }
    }
    const std::int32_t label = s.cluster_label[static_cast<std::size_t>(c)];
    if (label < 0) continue;
    out.labels[i] = label;
    const double ml = s.label_max_lambda[static_cast<std::size_t>(c)];
    out.probabilities[i] = ml > 0.0 ? std::min(ml, lambda) / ml : 1.0;
  }
  return out;
}

inline RowMatrixXd HdbscanPredictor::membership_vector(Eigen::Ref<const RowMatrixXd> query) const {
  const State& s = *state_;
  detail::check_query(s, query, "ds3d::HdbscanPredictor::membership_vector");
  RowMatrixXd out = RowMatrixXd::Zero(query.rows(), num_labels());
  if (!s.has_split || num_labels() == 0) return out;
  for (Eigen::Index i = 0; i < query.rows(); ++i) {
    const auto q = detail::query_row(query, i);
    detail::query_membership(s, q.data(), out.row(i).data());
  }
  return out;
}

inline RowMatrixXd HdbscanPredictor::all_points_membership_vectors() const {
  const State& s = *state_;
  const std::size_t nl = s.selected.size();
  RowMatrixXd out =
      RowMatrixXd::Zero(static_cast<Eigen::Index>(s.n), static_cast<Eigen::Index>(nl));
  if (!s.has_split || nl == 0) return out;
  // Outlier term exp(-(max_lambda / height)), then a softmax shifted by the global maximum.
  RowMatrixXd score(out.rows(), out.cols());
  double top = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < s.n; ++i) {
    const std::int64_t pc = s.point_parent[i];
    const double ml = s.leaf_max_lambda[static_cast<std::size_t>(pc)] + 1e-8;
    for (std::size_t l = 0; l < nl; ++l) {
      const double h = detail::merge_height(s, pc, s.point_lambda[i], s.selected[l]);
      const double v = std::exp(-(ml / h));
      score(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(l)) = v;
      if (!std::isnan(v)) top = std::max(top, v);
    }
  }
  std::vector<double> dist_vec(nl);
  std::vector<double> outlier(nl);
  for (std::size_t i = 0; i < s.n; ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    for (std::size_t l = 0; l < nl; ++l) {
      outlier[l] = std::exp(score(r, static_cast<Eigen::Index>(l)) - top);
    }
    detail::normalise_row(outlier.data(), nl);
    detail::distance_memberships(s, s.data.data() + i * s.dim, dist_vec.data());
    double* row = out.row(r).data();
    for (std::size_t l = 0; l < nl; ++l) row[l] = dist_vec[l] * outlier[l];
    detail::normalise_row(row, nl);
    const double p = detail::prob_in_some_cluster(s, s.point_parent[i], s.point_lambda[i], 0.0);
    for (std::size_t l = 0; l < nl; ++l) row[l] = std::isfinite(p) ? row[l] * p : 0.0;
  }
  return out;
}

namespace detail {

/// Cluster hierarchy of the fit: parents, births, per-cluster maximum lambda, point rows.
inline void predict_tree_from_fit(HdbscanPredictor::State& s, const HdbscanResult& fit) {
  constexpr const char* kFn = "ds3d::HdbscanPredictor";
  const auto nn = static_cast<std::int64_t>(s.n);
  std::int64_t max_id = nn;
  for (const auto& r : fit.condensed_tree) {
    DS3D_CHECK(r.parent >= nn && r.child >= 0 && (r.child < nn || r.child > r.parent), kFn,
               ": fit.condensed_tree row (", r.parent, ", ", r.child,
               ") does not belong to a fit of ", s.n, " points");
    max_id = std::max({max_id, r.parent, r.child});
  }
  const auto nc = static_cast<std::size_t>(max_id - nn + 1);
  s.cluster_parent.assign(nc, -1);
  s.cluster_birth.assign(nc, 0.0);
  s.leaf_max_lambda.assign(nc, 0.0);
  s.point_parent.assign(s.n, -1);
  s.point_lambda.assign(s.n, 0.0);
  for (const auto& r : fit.condensed_tree) {
    const auto pc = r.parent - nn;
    auto& lm = s.leaf_max_lambda[static_cast<std::size_t>(pc)];
    lm = std::max(lm, r.lambda_val);
    if (r.child < nn) {
      s.point_parent[static_cast<std::size_t>(r.child)] = pc;
      s.point_lambda[static_cast<std::size_t>(r.child)] = r.lambda_val;
    } else {
      s.cluster_parent[static_cast<std::size_t>(r.child - nn)] = pc;
      s.cluster_birth[static_cast<std::size_t>(r.child - nn)] = r.lambda_val;
    }
  }
  s.has_split = nc > 1;
  for (std::size_t i = 0; i < s.n && !fit.condensed_tree.empty(); ++i) {
    DS3D_CHECK(s.point_parent[i] >= 0, kFn, ": point ", i, " has no row in fit.condensed_tree");
  }
}

/// Labels per cluster (through the selected ancestor) and the exemplars of each label: the
/// points of its leaf clusters that carry the leaf's maximum lambda.
inline void predict_labels_from_fit(HdbscanPredictor::State& s, const HdbscanResult& fit) {
  const auto nn = static_cast<std::int64_t>(s.n);
  const std::size_t nc = s.cluster_parent.size();
  s.cluster_label.assign(nc, -1);
  for (std::size_t l = 0; l < fit.selected_clusters.size(); ++l) {
    const std::int64_t c = fit.selected_clusters[l] - nn;
    DS3D_CHECK(c >= 0 && static_cast<std::size_t>(c) < nc,
               "ds3d::HdbscanPredictor: "
               "fit.selected_clusters[",
               l, "] = ", fit.selected_clusters[l], " is not a cluster");
    s.selected.push_back(c);
    s.cluster_label[static_cast<std::size_t>(c)] = static_cast<std::int32_t>(l);
  }
  std::vector<std::int64_t> owner(nc, -1);  // selected ancestor-or-self
  for (std::size_t c = 0; c < nc; ++c) {    // ids grow downwards: parents come first
    if (s.cluster_label[c] >= 0) {
      owner[c] = static_cast<std::int64_t>(c);
    } else if (c > 0) {
      owner[c] = owner[static_cast<std::size_t>(s.cluster_parent[c])];
    }
  }
  s.label_max_lambda.assign(nc, 0.0);
  for (std::size_t c = 0; c < nc; ++c) {
    if (owner[c] < 0) continue;
    s.cluster_label[c] = s.cluster_label[static_cast<std::size_t>(owner[c])];
    s.label_max_lambda[c] = s.leaf_max_lambda[static_cast<std::size_t>(owner[c])];
  }
  std::vector<char> is_leaf(nc, 1);
  for (std::size_t c = 1; c < nc; ++c) is_leaf[static_cast<std::size_t>(s.cluster_parent[c])] = 0;
  s.exemplars.assign(s.selected.size(), {});
  for (const auto& r : fit.condensed_tree) {
    if (r.child >= nn) continue;
    const auto pc = static_cast<std::size_t>(r.parent - nn);
    if (is_leaf[pc] && owner[pc] >= 0 && r.lambda_val == s.leaf_max_lambda[pc]) {
      const auto label = s.cluster_label[pc];
      s.exemplars[static_cast<std::size_t>(label)].push_back(static_cast<std::uint32_t>(r.child));
    }
  }
}

}  // namespace detail

inline HdbscanPredictor::HdbscanPredictor(Eigen::Ref<const RowMatrixXd> points,
                                          const HdbscanResult& fit, const HdbscanParams& params,
                                          int num_threads) {
  constexpr const char* kFn = "ds3d::HdbscanPredictor";
  params.validate();
  const int threads = detail::resolve_num_threads(num_threads, kFn);
  auto s = std::make_shared<State>();
  s->n = static_cast<std::size_t>(points.rows());
  s->dim = static_cast<std::size_t>(points.cols());
  DS3D_CHECK(fit.labels.size() == s->n, kFn, ": points has ", s->n, " rows but the fit ",
             fit.labels.size(), " labels");
  s->data.resize(s->n * s->dim);
  for (std::size_t i = 0; i < s->n; ++i) {
    for (std::size_t j = 0; j < s->dim; ++j) {
      const double v = points(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
      DS3D_CHECK(std::isfinite(v), kFn, ": points row ", i, " column ", j, " is not finite (got ",
                 v, ")");
      s->data[i * s->dim + j] = v;
    }
  }
  s->rows = detail::DenseRowsNd{s->data.data(), s->n, s->dim};
  const int ms = params.min_samples > 0 ? params.min_samples : params.min_cluster_size;
  s->k = std::max(1, std::min(ms, static_cast<int>(s->n)));
  detail::predict_tree_from_fit(*s, fit);
  detail::predict_labels_from_fit(*s, fit);
  s->core.assign(s->n, 0.0);
  if (s->k > 1) {
    s->core = detail::knn_core_distances(s->rows, static_cast<std::size_t>(s->k - 1), threads);
  }
  if (s->n > 0) {
    s->tree = std::make_unique<detail::KdTreeNd<-1>>(static_cast<int>(s->dim), s->rows,
                                                     nanoflann::KDTreeSingleIndexAdaptorParams(16));
    s->tree->buildIndex();
  }
  state_ = std::move(s);
}

}  // namespace ds3d
