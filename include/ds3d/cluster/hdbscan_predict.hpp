// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file hdbscan_predict.hpp
/// @brief Cluster labels and soft memberships of new points for a finished hdbscan() fit, with
/// the semantics of the reference library's `hdbscan.prediction` (0.8.43): `approximate_predict`,
/// `membership_vector` and `all_points_membership_vectors`.
///
/// The fit is kept as it is: a new point is hung below the cluster of its nearest
/// mutual-reachability neighbour at the lambda of that connection (McInnes, Healy & Astels 2017,
/// "Predicting clusters for new points"); no cluster is re-selected. Soft membership mixes a
/// distance term (inverse distance to each cluster's exemplars, the points of its leaves that
/// persist longest) with an outlier term (how deep in the tree the point merges with each
/// cluster), then scales by the probability of being in any cluster, as the reference does.

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <vector>

#include "ds3d/cluster/hdbscan.hpp"

namespace ds3d {

/// Output of HdbscanPredictor::approximate_predict().
struct HdbscanPrediction {
  std::vector<std::int32_t> labels;   ///< label of the fit (0..num_clusters-1) or -1 = noise
  std::vector<double> probabilities;  ///< membership strength in [0, 1]; 0 for noise
};

/// Prediction data of one hdbscan() fit (the reference's `generate_prediction_data()`): a KD-tree
/// over the fitted points, their core distances and the cluster hierarchy.
/// @note Immutable after construction; copies share the data, and const member functions are
///   safe to call concurrently. Euclidean metric only, distances summed in dimension order like
///   hdbscan() (so results are bitwise reproducible).
class HdbscanPredictor {
 public:
  /// Builds the prediction data.
  /// @param points the N × D points that were clustered, exactly as passed to hdbscan() (when
  ///   hdbscan() was given a scale, pass the scaled coordinates here and to the queries).
  /// @param fit the result of hdbscan(points, params).
  /// @param params the parameters of that fit; the neighbourhood size of the prediction is
  ///   min_samples (or min_cluster_size when min_samples = 0), clamped to N, as in the reference.
  /// @param num_threads threads for the core distances; 0 = hardware concurrency, >= 0.
  /// @throws ds3d::InvalidArgument when points and fit do not belong together (row count,
  ///   condensed tree), for a non-finite coordinate or bad params.
  /// @note O(N log N) for the core distances plus O(N + rows of the condensed tree).
  HdbscanPredictor(Eigen::Ref<const RowMatrixXd> points, const HdbscanResult& fit,
                   const HdbscanParams& params, int num_threads = 1);

  /// Labels and probabilities of new points in the clustering of the fit (reference
  /// `approximate_predict`): the nearest fitted point by mutual reachability decides the branch
  /// of the condensed tree, the lambda of that connection the depth.
  /// @param query M × D points, finite, D = dim().
  /// @throws ds3d::InvalidArgument for a wrong column count or a non-finite coordinate.
  /// @note O(M · (k log N + depth of the cluster tree)), k = 2 · min_samples. A fit without any
  ///   cluster split predicts noise for every point (as the reference).
  [[nodiscard]] HdbscanPrediction approximate_predict(Eigen::Ref<const RowMatrixXd> query) const;

  /// Soft membership of new points (reference `membership_vector`): M × num_labels(), row i the
  /// probability that query point i belongs to each cluster, in label order. Rows sum to the
  /// probability of being in some cluster (<= 1).
  /// @throws ds3d::InvalidArgument as approximate_predict().
  /// @note O(M · (k log N + E · D + C · depth)), E exemplar points, C clusters. All zeros when the
  ///   fit has no cluster split.
  [[nodiscard]] RowMatrixXd membership_vector(Eigen::Ref<const RowMatrixXd> query) const;

  /// Soft membership of every fitted point (reference `all_points_membership_vectors`),
  /// N × num_labels(), from the points' own rows of the condensed tree.
  /// @note O(N · (E · D + C · depth)). All zeros when the fit has no cluster split.
  [[nodiscard]] RowMatrixXd all_points_membership_vectors() const;

  /// Indices (into the fitted points) of the exemplars of cluster `label`: the points of its
  /// leaf clusters that leave them last. @throws ds3d::InvalidArgument for a bad label.
  [[nodiscard]] const std::vector<std::uint32_t>& exemplars(int label) const;

  [[nodiscard]] std::size_t size() const noexcept;  ///< N, number of fitted points
  [[nodiscard]] std::size_t dim() const noexcept;   ///< D, number of columns
  /// Columns of the membership matrices: the selected clusters of the fit.
  [[nodiscard]] int num_labels() const noexcept;
  /// Neighbourhood size used for prediction (min_samples or min_cluster_size, clamped to N).
  [[nodiscard]] int min_samples() const noexcept;
  /// Core distance per fitted point as the prediction uses it: distance to the min_samples()-th
  /// nearest fitted point, the point itself included (reference `PredictionData`).
  [[nodiscard]] const std::vector<double>& core_distances() const noexcept;

  struct State;  ///< shared, immutable prediction data (detail)

 private:
  std::shared_ptr<const State> state_;
};

}  // namespace ds3d

#include "ds3d/detail/hdbscan_predict_impl.hpp"
