// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// nanoflann 3-D float KD-tree over any PointCloud (read through PointCloudTraits), optionally
// restricted to a subset of the input (e.g. its finite points). Not API.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <nanoflann.hpp>

#include "ds3d/cloud.hpp"

namespace ds3d::detail {

/// nanoflann dataset adaptor: point i of the tree is cloud point subset[i] (or i if no subset).
template <PointCloud C>
struct KdTreeCloudAdaptor {
  const C& cloud;
  const std::vector<std::uint32_t>* subset = nullptr;  ///< tree index -> input index

  [[nodiscard]] std::size_t kdtree_get_point_count() const {
    return subset != nullptr ? subset->size() : cloud::size(cloud);
  }
  [[nodiscard]] float kdtree_get_pt(std::size_t i, std::size_t dim) const {
    const std::size_t j = subset != nullptr ? (*subset)[i] : i;
    return cloud::point(cloud, j)[static_cast<Eigen::Index>(dim)];
  }
  template <class Box>
  bool kdtree_get_bbox(Box& /*unused*/) const {
    return false;  // let nanoflann compute it
  }
};

/// 3-D float KD-tree; distances accumulated in double (L2, squared).
template <PointCloud C>
using KdTree3f = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, KdTreeCloudAdaptor<C>, double>, KdTreeCloudAdaptor<C>, 3,
    std::uint32_t>;

/// nanoflann result set that counts neighbours within a radius and stops the search at `limit`.
/// nanoflann prunes with `search_r2` (its float differences); `accept(index)` decides exactly.
template <class Accept>
class CountingRadiusResultSet {
 public:
  CountingRadiusResultSet(double search_r2, std::uint32_t limit, Accept accept)
      : search_r2_(search_r2), limit_(limit), accept_(accept) {}
  void init() { count_ = 0; }
  [[nodiscard]] std::size_t size() const { return count_; }
  [[nodiscard]] bool full() const { return true; }
  [[nodiscard]] double worstDist() const { return search_r2_; }  // NOLINT(readability-*)
  /// Returns false (stop the search) once `limit` neighbours were accepted.
  bool addPoint(double /*dist*/, std::uint32_t index) {  // NOLINT(readability-*)
    if (accept_(index)) ++count_;
    return count_ < limit_;
  }
  [[nodiscard]] std::uint32_t count() const { return count_; }

 private:
  double search_r2_;
  std::uint32_t limit_;
  Accept accept_;
  std::uint32_t count_ = 0;
};

/// nanoflann result set for the nearest neighbour within a squared radius: the same point as a
/// 1-NN search (the first visited on ties) when that lies within `r2` (inclusive), found with the
/// radius as the initial bound, so that the search prunes from the start; none otherwise.
class NearestWithinResultSet {
 public:
  explicit NearestWithinResultSet(double r2)
      : best_(std::nextafter(r2, std::numeric_limits<double>::infinity())) {}
  [[nodiscard]] bool full() const { return true; }
  [[nodiscard]] double worstDist() const { return best_; }  // NOLINT(readability-*)
  bool addPoint(double dist, std::uint32_t index) {         // NOLINT(readability-*)
    if (dist < best_) {
      best_ = dist;
      index_ = index;
      found_ = true;
    }
    return true;
  }
  [[nodiscard]] bool found() const { return found_; }
  [[nodiscard]] std::uint32_t index() const { return index_; }

 private:
  double best_;
  std::uint32_t index_ = 0;
  bool found_ = false;
};

}  // namespace ds3d::detail
