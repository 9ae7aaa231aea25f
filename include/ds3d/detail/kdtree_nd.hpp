// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// N-dimensional nanoflann adaptor over a dense row-major double array, with a Euclidean metric
// that sums squared differences strictly in dimension order (bitwise reproducible against the
// reference hdbscan / sklearn KDTree, see docs/hdbscan.md). Not API. The 3-D float adaptor of
// the preprocessing components lives in detail/kdtree.hpp; the two are kept apart on purpose.

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "ds3d/detail/parallel.hpp"

namespace ds3d::detail {

/// Prevents the compiler from contracting `acc + p` into an FMA with the product that made `p`.
/// Only needed when the target has FMA (otherwise no contraction is possible); the empty asm makes
/// `p` opaque at zero cost. Clang also honours the `fp contract(off)` pragma in the callers.
inline double no_contract(double p) {
#if defined(__FMA__) && defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
  asm("" : "+x"(p));
#elif defined(__GNUC__) && defined(__aarch64__)
  asm("" : "+w"(p));
#endif
  return p;
}

/// Squared Euclidean distance summed in dimension order, no FMA: sum_j (a_j - b_j)^2.
inline double sq_dist_seq(const double* a, const double* b, std::size_t dim) {
  double s = 0.0;
  for (std::size_t j = 0; j < dim; ++j) {
    const double d = a[j] - b[j];
    s += no_contract(d * d);
  }
  return s;
}

/// Dense row-major point set (n × dim, doubles) as a nanoflann dataset.
struct DenseRowsNd {
  const double* data = nullptr;
  std::size_t n = 0;
  std::size_t dim = 0;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return n; }
  [[nodiscard]] double kdtree_get_pt(std::size_t i, std::size_t j) const {
    return data[i * dim + j];
  }
  template <class Bbox>
  bool kdtree_get_bbox(Bbox& /*bb*/) const {
    return false;
  }
};

/// nanoflann distance functor: squared L2 summed in dimension order (see sq_dist_seq).
struct SeqL2Nd {
  using ElementType = double;
  using DistanceType = double;
  const DenseRowsNd& ds;
  explicit SeqL2Nd(const DenseRowsNd& d) : ds(d) {}
  [[nodiscard]] double evalMetric(const double* a, std::size_t b, std::size_t size) const {
    return sq_dist_seq(a, ds.data + b * ds.dim, size);
  }
  template <class U, class V>
  [[nodiscard]] double accum_dist(const U a, const V b, std::size_t /*dim*/) const {
    const double d = a - b;
    return d * d;
  }
};

using KdTreeNd = nanoflann::KDTreeSingleIndexAdaptor<SeqL2Nd, DenseRowsNd, -1, std::uint32_t>;

/// Distance from each point to its k-th nearest *other* point (the (k+1)-th smallest distance
/// including the point itself), exactly as sqrt of sq_dist_seq. Requires 1 <= k < n.
/// O(n log n) expected for low dimension; deterministic for any num_threads.
inline std::vector<double> knn_core_distances(const DenseRowsNd& ds, std::size_t k,
                                              int num_threads) {
  std::vector<double> core(ds.n, 0.0);
  KdTreeNd tree(static_cast<int>(ds.dim), ds, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  tree.buildIndex();
  parallel_for(ds.n, num_threads, [&](std::size_t begin, std::size_t end, std::size_t) {
    std::vector<std::uint32_t> idx(k + 1);
    std::vector<double> d2(k + 1);
    for (std::size_t i = begin; i < end; ++i) {
      const std::size_t found = tree.knnSearch(ds.data + i * ds.dim, k + 1, idx.data(), d2.data());
      // Recompute the selected squared distances exactly; the (k+1)-th value is the largest.
      double worst = 0.0;
      for (std::size_t t = 0; t < found; ++t) {
        worst =
            std::max(worst, sq_dist_seq(ds.data + i * ds.dim, ds.data + idx[t] * ds.dim, ds.dim));
      }
      core[i] = std::sqrt(worst);
    }
  });
  return core;
}

}  // namespace ds3d::detail
