// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file hdbscan.hpp
/// @brief HDBSCAN* clustering (Campello, Moulavi & Sander 2013; McInnes & Healy 2017) that
/// reproduces the partitions of the reference Python library `hdbscan` 0.8.43.
///
/// Pipeline (each step names the reference rule it reproduces, see docs/hdbscan.md):
///  1. core distance κ(i) = distance to the k-th nearest *other* point (exact KD-tree kNN, k + 1
///     neighbours including the point itself; k = min_samples, default min_cluster_size,
///     clamped to n - 1);
///  2. mutual reachability d_mr(i,j) = max{κ(i), κ(j), d(i,j)} (3DS-SLAM §III-C, Eq. 4);
///  3. exact minimum spanning tree of the complete d_mr graph, by
///     - Prim on the implicit dense graph: O(n²·D) time, O(n·D) memory (small n), or
///     - KD-tree Borůvka (McInnes & Healy 2017, §3; its tree also serves the kNN), seeded from
///       each point's core ball: O(log n) rounds of pruned KD-tree searches, about
///       O(n log² n) for low-dimensional data in practice, O(n·D) memory (large n);
///  4. single-linkage tree (scipy linkage layout), condensed tree, cluster stability, excess of
///     mass (EOM) or leaf selection, cluster_selection_epsilon, allow_single_cluster;
///  5. membership probabilities, GLOSH outlier scores (Campello et al. 2015) and persistence.
///
/// Distances are sqrt(Σ_j (a_j − b_j)²) summed in dimension order without FMA contraction
/// (on FMA targets an empty asm barrier on each product keeps it apart whatever -ffp-contract
/// says; the runtime-dispatched AVX2 / AVX-512F Prim steps put that barrier on every product
/// unconditionally), so core distances and MST weights match the reference bit for bit. Do not
/// build with -ffast-math.

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

#include "ds3d/detail/core_separate.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// Row-major N × D matrix of doubles (numpy-compatible).
using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// How flat clusters are chosen from the condensed tree.
enum class ClusterSelection : std::uint8_t {
  kEom,   ///< excess of mass: the most stable antichain of clusters
  kLeaf,  ///< the leaves of the cluster tree (fine-grained, homogeneous clusters)
};

/// Minimum-spanning-tree algorithm. All give the same MST weights (exact MST); under exactly
/// equal mutual-reachability weights they may pick different (equally minimal) edges.
enum class MstAlgorithm : std::uint8_t {
  kAuto,     ///< Prim below 3000 points or above 8 dimensions, Borůvka otherwise
  kPrims,    ///< Prim on the implicit dense graph: O(n²·D) time, O(n·D) memory
  kBoruvka,  ///< KD-tree Borůvka: ~O(n log² n) for low D, O(n·D) memory
};

/// Parameters of hdbscan(); names and defaults follow the reference library.
struct HdbscanParams {
  int min_cluster_size = 5;  ///< smallest group counted as a cluster, >= 2
  int min_samples = 0;  ///< k of the core distance (k-th nearest other point); 0 = min_cluster_size
  ClusterSelection cluster_selection_method = ClusterSelection::kEom;  ///< eom or leaf
  bool allow_single_cluster = false;  ///< let the root be selected as the only cluster
  double cluster_selection_epsilon =
      0.0;                   ///< merge clusters born below this distance, >= 0 [data units]
  int max_cluster_size = 0;  ///< EOM: never select clusters larger than this; 0 = no limit, >= 0
  MstAlgorithm algorithm = MstAlgorithm::kAuto;  ///< MST construction
  int num_threads = 1;  ///< threads for kNN and Borůvka; 0 = hardware concurrency, >= 0
  /// Prim (coordinates) only: order equal-weight merges as the reference does (numpy's quicksort
  /// of Prim's (previous, new) node pairs) instead of a stable sort of the MST edges, so that
  /// points whose cluster depends on such ties match it too. Off: existing results unchanged.
  bool reference_tie_order = false;
  /// Throws ds3d::InvalidArgument naming the first bad field and its value.
  void validate() const;
};

/// One row of the condensed tree (reference `condensed_tree_` layout). Ids < n are points; the
/// root cluster is n and clusters are numbered n, n+1, … in breadth-first order.
struct CondensedTreeRow {
  std::int64_t parent = 0;      ///< cluster id
  std::int64_t child = 0;       ///< point index (< n) or cluster id (>= n)
  double lambda_val = 0.0;      ///< 1 / distance at which child leaves parent; +inf for distance 0
  std::int64_t child_size = 0;  ///< 1 for a point, else the child cluster's size
};

/// One merge of the single-linkage tree (scipy linkage layout): row i creates node n + i.
struct SingleLinkageRow {
  std::int64_t left = 0;   ///< node id (< n: point)
  std::int64_t right = 0;  ///< node id
  double distance = 0.0;   ///< mutual-reachability distance of the merge
  std::int64_t size = 0;   ///< points below the new node
};

/// One edge of the mutual-reachability minimum spanning tree.
struct MstEdge {
  std::uint32_t from = 0;  ///< point index
  std::uint32_t to = 0;    ///< point index
  double weight = 0.0;     ///< d_mr(from, to)
};

/// Output of hdbscan(). For n < 2 every point is noise and the trees are empty (the reference
/// raises an error for n = 1).
struct HdbscanResult {
  std::vector<std::int32_t> labels;   ///< cluster id 0..num_clusters-1, or -1 = noise
  std::vector<double> probabilities;  ///< membership strength in [0, 1]; 0 for noise
  /// GLOSH score in [0, 1]. As in the reference, a point whose parent cluster contains exact
  /// duplicates below it (subtree max lambda = +inf) while its own lambda is finite gets NaN
  /// (inf/inf); this is the only place a NaN can appear, and only with duplicated points.
  std::vector<double> outlier_scores;
  std::vector<CondensedTreeRow> condensed_tree;       ///< reference row order
  std::vector<SingleLinkageRow> single_linkage_tree;  ///< n - 1 rows, sorted by distance
  std::vector<MstEdge> min_spanning_tree;             ///< n - 1 edges, sorted by weight
  std::vector<double> core_distances;                 ///< κ(i) per point
  /// Per selected cluster, in label order (reference formula: stability / (members · max λ),
  /// 1 when undefined). Has one entry more than num_clusters only when allow_single_cluster
  /// selected the root and no point passed the root-label rule (all noise), like the reference.
  std::vector<double> cluster_persistence;
  /// Condensed-tree id (>= n) of each selected cluster, in label order (the reference's
  /// `_select_clusters()`, sorted); same length as cluster_persistence.
  std::vector<std::int64_t> selected_clusters;
  int num_clusters = 0;           ///< number of labels in use (max label + 1)
  int min_samples_effective = 0;  ///< k actually used (after clamping)
};

/// HDBSCAN* of N points in D dimensions, Euclidean, optionally scaled per dimension.
/// @param points N × D row-major coordinates, finite; N >= 0, D >= 1.
/// @param scale per-dimension weights (size D, finite, > 0) multiplied into the coordinates
///   before clustering (e.g. {1, 1, 100} to mix pixels and metres); empty = all ones.
/// @param params see HdbscanParams.
/// @throws ds3d::InvalidArgument for bad params, a non-finite coordinate (names the row and
///   column), or a bad scale.
/// @note Complexity: kNN O(n log n); MST per HdbscanParams::algorithm; tree steps O(n log n);
///   memory O(n·D). Output is identical for every num_threads. n < min_samples is handled like
///   the reference (k clamped to n - 1).
[[nodiscard]] DS3D_CORE_INLINE HdbscanResult hdbscan(Eigen::Ref<const RowMatrixXd> points,
                                                     const HdbscanParams& params = {},
                                                     const std::vector<double>& scale = {});

/// HDBSCAN* on a precomputed symmetric distance matrix (Prim on the dense matrix).
/// @param distances N × N, finite, >= 0, symmetric, zero diagonal.
/// @param params see HdbscanParams (algorithm is ignored).
/// @throws ds3d::InvalidArgument naming the first bad entry or parameter.
/// @note O(n²) time, O(n) extra memory beyond the matrix.
[[nodiscard]] DS3D_CORE_INLINE HdbscanResult
hdbscan_precomputed(Eigen::Ref<const RowMatrixXd> distances, const HdbscanParams& params = {});

/// Renders a ClusterSelection as the reference's string ("eom" or "leaf").
[[nodiscard]] DS3D_CORE_INLINE std::string to_string(ClusterSelection method);
/// Renders an MstAlgorithm as a string ("auto", "prims" or "boruvka").
[[nodiscard]] DS3D_CORE_INLINE std::string to_string(MstAlgorithm algorithm);

}  // namespace ds3d

#if !defined(DS3D_CORE_SEPARATE) || defined(DS3D_CORE_IMPLEMENTATION)
#include "ds3d/detail/hdbscan_impl.hpp"
#endif
