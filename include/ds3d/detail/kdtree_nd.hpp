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
/// `p` opaque at zero cost (GCC and Clang, x86-64 and AArch64).
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

template <int kDim>
using KdTreeNd = nanoflann::KDTreeSingleIndexAdaptor<SeqL2Nd, DenseRowsNd, kDim, std::uint32_t>;

/// Core distances and neighbour lists: core[i] is the distance from i to its k-th nearest *other*
/// point (the (k+1)-th smallest distance including the point itself), exactly
/// sqrt(sq_dist_seq); if `neighbors` is non-null it receives the k+1 neighbour ids of each point
/// (row-major n × (k+1), nearest first, the point itself usually first). Requires 1 <= k < n.
/// Queries run in the tree's leaf order for cache locality. O(n log n) expected for low
/// dimension; deterministic for any num_threads.
template <int kDim>
void knn_core_distances_impl(const DenseRowsNd& ds, std::size_t k, int num_threads,
                             std::vector<double>& core, std::vector<std::uint32_t>* neighbors) {
  core.assign(ds.n, 0.0);
  if (neighbors != nullptr) neighbors->assign(ds.n * (k + 1), 0U);
  KdTreeNd<kDim> tree(static_cast<int>(ds.dim), ds, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  tree.buildIndex();
  const std::vector<std::uint32_t>& order = tree.vAcc;  // points grouped by leaf
  parallel_chunks(ds.n, std::size_t{16} * static_cast<std::size_t>(std::max(1, num_threads)),
                  num_threads, [&](std::size_t begin, std::size_t end, std::size_t) {
                    std::vector<std::uint32_t> idx(k + 1);
                    std::vector<double> d2(k + 1);
                    for (std::size_t o = begin; o < end; ++o) {
                      const std::size_t i = order[o];
                      const double* q = ds.data + i * ds.dim;
                      const std::size_t found = tree.knnSearch(q, k + 1, idx.data(), d2.data());
                      // Recompute the selected squared distances exactly; the largest one is
                      // the (k+1)-th smallest distance.
                      double worst = 0.0;
                      for (std::size_t t = 0; t < found; ++t) {
                        worst = std::max(worst, sq_dist_seq(q, ds.data + idx[t] * ds.dim, ds.dim));
                      }
                      core[i] = std::sqrt(worst);
                      if (neighbors != nullptr) {
                        std::copy_n(idx.data(), found, neighbors->data() + i * (k + 1));
                        for (std::size_t t = found; t <= k; ++t)
                          (*neighbors)[i * (k + 1) + t] = idx[0];
                      }
                    }
                  });
}

inline std::vector<double> knn_core_distances(const DenseRowsNd& ds, std::size_t k, int num_threads,
                                              std::vector<std::uint32_t>* neighbors = nullptr) {
  std::vector<double> core;
  if (ds.dim == 3) {
    knn_core_distances_impl<3>(ds, k, num_threads, core, neighbors);
  } else if (ds.dim == 2) {
    knn_core_distances_impl<2>(ds, k, num_threads, core, neighbors);
  } else {
    knn_core_distances_impl<-1>(ds, k, num_threads, core, neighbors);
  }
  return core;
}

}  // namespace ds3d::detail
