// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// N-dimensional nanoflann adaptor over a dense row-major double array, with a Euclidean metric
// that sums squared differences strictly in dimension order (bitwise reproducible against the
// reference hdbscan / sklearn KDTree, see docs/hdbscan.md). Not API. The 3-D float adaptor of
// the preprocessing components lives in detail/kdtree.hpp; the two are kept apart on purpose.

#include <nanoflann.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#if defined(__AVX2__)
#include <immintrin.h>
#elif defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "ds3d/detail/box_bounds.hpp"
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

#if defined(__SSE2__)
/// no_contract() for packed doubles in an SSE or AVX register (__m128d, __m256d): keeps each
/// product a separate rounding (no FMA).
template <class V>
inline V no_contract_simd(V v) {
#if defined(__FMA__) && defined(__GNUC__)
  asm("" : "+x"(v));
#endif
  return v;
}
#endif

/// Gap of a coordinate to an interval [lo, hi] from a = lo - q and b = q - hi: max{a, b, 0}. At
/// most one of a, b is positive, so this equals `a > 0 ? a : (b > 0 ? b : 0)` (up to the sign of
/// a zero, which squaring removes), but compiles to max instructions instead of two
/// unpredictable branches.
inline double gap(double a, double b) {
#if defined(__SSE2__)
  // maxsd(x, y) = x > y ? x : y; written out, GCC 12 may still emit a branch.
  const __m128d m = _mm_max_sd(_mm_set_sd(a), _mm_set_sd(b));
  return _mm_cvtsd_f64(_mm_max_sd(m, _mm_setzero_pd()));
#else
  const double m = a > b ? a : b;
  return m > 0.0 ? m : 0.0;
#endif
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

/// Up to this many points knn_core_distances uses KnnTreeSmall instead of nanoflann (measured
/// with callgrind, see docs/hdbscan.md).
inline constexpr std::size_t kSmallKnnMaxPoints = 4096;

/// Exact kNN for small n: a median-split KD-tree over points copied in tree order, queried in
/// leaf order. Each query first scans its own leaf (a tight bound at once), then descends from
/// the root skipping boxes whose squared distance exceeds the current (k+1)-th smallest squared
/// distance. Box distances are computed like sq_dist_seq on clamped coordinates, so by monotone
/// rounding they bound every point inside from below: the result equals brute force. Ties are
/// ordered by (distance, point id). Same contract and outputs as knn_core_distances_impl.
template <int kDim>
class KnnTreeSmall {
 public:
  explicit KnnTreeSmall(const DenseRowsNd& ds)
      : n_(ds.n), dim_(kDim > 0 ? static_cast<std::size_t>(kDim) : ds.dim) {
    order_.resize(n_);
    for (std::size_t i = 0; i < n_; ++i) order_[i] = static_cast<std::uint32_t>(i);
    nodes_.reserve(4 * (n_ / kLeafSize + 1));
    lo_.reserve(nodes_.capacity() * dim_);
    hi_.reserve(nodes_.capacity() * dim_);
    build(ds.data, 0, static_cast<std::uint32_t>(n_));
    pts_.resize(n_ * dim_);
    stride_ = n_ + kLeafSize;  // padding: a leaf scan always reads kLeafSize lanes
    soa_.assign(stride_ * dim_, 0.0);
    for (std::size_t s = 0; s < n_; ++s) {
      const double* src = ds.data + static_cast<std::size_t>(order_[s]) * dim_;
      std::copy_n(src, dim_, pts_.data() + s * dim_);
      for (std::size_t j = 0; j < dim_; ++j) soa_[j * stride_ + s] = src[j];
    }
  }

  /// Core distances only (no neighbour ids): core[i] = sqrt of the (k+1)-th smallest squared
  /// distance from i, itself included. The value does not depend on how ties are ordered, so
  /// the kept lists hold distances only and candidates equal to the current (k+1)-th are
  /// skipped. Queries are batched per leaf: every query of a leaf first scans its own leaf,
  /// which bounds the radius R of the whole leaf; the other leaves whose box lies within R of
  /// this leaf's box are listed once, nearest first, and each query walks that list until the
  /// box-to-box distance reaches its own (k+1)-th distance. Leaves are scanned as vectorisable
  /// passes over per-dimension coordinates. All bounds are exact lower bounds (monotone
  /// rounding), so the result is bitwise that of brute force with sq_dist_seq.
  void run_core_only(std::size_t k, int num_threads, std::vector<double>& core) const {
    const std::size_t kk = k + 1;
    const std::size_t ks = list_stride(kk);
    const std::size_t d = dim();
    core.assign(n_, 0.0);
    std::vector<std::uint32_t> leaves;
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
      if (nodes_[i].left < 0) leaves.push_back(static_cast<std::uint32_t>(i));
    }
    const std::size_t nl = leaves.size();
    parallel_chunks(nl, std::size_t{16} * static_cast<std::size_t>(std::max(1, num_threads)),
                    num_threads, [&](std::size_t begin, std::size_t end, std::size_t) {
                      std::vector<double> bd;
                      std::vector<double> worst;
                      std::vector<std::pair<double, std::uint32_t>> cand;  // (box-to-box d², node)
                      for (std::size_t li = begin; li < end; ++li) {
                        const auto leaf = leaves[li];
                        const Node& ln = nodes_[leaf];
                        const std::size_t m = ln.end - ln.begin;
                        bd.assign(m * ks, std::numeric_limits<double>::infinity());
                        worst.assign(m, std::numeric_limits<double>::infinity());
                        double r2 = 0.0;
                        for (std::size_t qi = 0; qi < m; ++qi) {
                          const double* q = pts_.data() + (ln.begin + qi) * d;
                          scan_core(q, ln, kk, bd.data() + qi * ks, worst[qi]);
                          r2 = std::max(r2, worst[qi]);
                        }
                        cand.clear();
                        for (std::size_t lj = 0; lj < nl; ++lj) {
                          if (lj == li) continue;
                          const double bb = box_box_dist2(leaf, leaves[lj]);
                          if (bb < r2) cand.emplace_back(bb, leaves[lj]);
                        }
                        std::sort(cand.begin(), cand.end());
                        for (std::size_t qi = 0; qi < m; ++qi) {
                          const double* q = pts_.data() + (ln.begin + qi) * d;
                          for (const auto& [bb, node] : cand) {
                            if (bb >= worst[qi]) break;  // this and all later leaves are too far
                            if (box_dist2(q, node) >= worst[qi]) continue;
                            scan_core(q, nodes_[node], kk, bd.data() + qi * ks, worst[qi]);
                          }
                          core[order_[ln.begin + qi]] = std::sqrt(worst[qi]);
                        }
                      }
                    });
  }

  void run(std::size_t k, int num_threads, std::vector<double>& core,
           std::vector<std::uint32_t>* neighbors) const {
    const std::size_t kk = k + 1;
    core.assign(n_, 0.0);
    if (neighbors != nullptr) neighbors->assign(n_ * kk, 0U);
    std::vector<std::uint32_t> leaves;
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
      if (nodes_[i].left < 0) leaves.push_back(static_cast<std::uint32_t>(i));
    }
    parallel_chunks(
        leaves.size(), std::size_t{16} * static_cast<std::size_t>(std::max(1, num_threads)),
        num_threads, [&](std::size_t begin, std::size_t end, std::size_t) {
          std::vector<double> bd(kk);
          std::vector<std::uint32_t> bi(kk);
          for (std::size_t li = begin; li < end; ++li) {
            const auto leaf = leaves[li];
            const Node& ln = nodes_[leaf];
            for (auto s = ln.begin; s < ln.end; ++s) {
              const std::size_t cnt = query(s, leaf, kk, bd.data(), bi.data());
              const std::uint32_t i = order_[s];
              core[i] = std::sqrt(bd[cnt - 1]);
              if (neighbors != nullptr) {
                std::copy_n(bi.data(), cnt, neighbors->data() + static_cast<std::size_t>(i) * kk);
                for (std::size_t t = cnt; t < kk; ++t) {
                  (*neighbors)[static_cast<std::size_t>(i) * kk + t] = bi[0];
                }
              }
            }
          }
        });
  }

 private:
  struct Node {
    std::uint32_t begin, end;
    std::int32_t left, right;  // -1 for leaves
  };
  static constexpr std::uint32_t kLeafSize = 16;

  [[nodiscard]] std::size_t dim() const { return kDim > 0 ? static_cast<std::size_t>(kDim) : dim_; }

  std::int32_t build(const double* data, std::uint32_t b, std::uint32_t e) {
    const auto id = static_cast<std::int32_t>(nodes_.size());
    nodes_.push_back({b, e, -1, -1});
    const std::size_t d = dim();
    lo_.resize(nodes_.size() * d);
    hi_.resize(nodes_.size() * d);
    double* lo = lo_.data() + static_cast<std::size_t>(id) * d;
    double* hi = hi_.data() + static_cast<std::size_t>(id) * d;
    for (std::size_t j = 0; j < d; ++j) {
      lo[j] = data[static_cast<std::size_t>(order_[b]) * d + j];
      hi[j] = lo[j];
    }
    if constexpr (kDim == 3) {  // the loop below with the box in registers (same min/max order)
      extend_box3(data, order_.data(), b + 1, e, lo, hi);
    } else {
      for (auto i = b + 1; i < e; ++i) {
        const double* p = data + static_cast<std::size_t>(order_[i]) * d;
        for (std::size_t j = 0; j < d; ++j) {
          lo[j] = std::min(lo[j], p[j]);
          hi[j] = std::max(hi[j], p[j]);
        }
      }
    }
    if (e - b <= kLeafSize) return id;
    std::size_t split = 0;
    for (std::size_t j = 1; j < d; ++j) {
      if (hi[j] - lo[j] > hi[split] - lo[split]) split = j;
    }
    if (!(hi[split] > lo[split])) return id;  // all points identical: one leaf
    const auto mid = b + (e - b) / 2;
    select_rank(data + split, b, mid, e);
    const auto l = build(data, b, mid);
    const auto r = build(data, mid, e);
    nodes_[static_cast<std::size_t>(id)].left = l;
    nodes_[static_cast<std::size_t>(id)].right = r;
    return id;
  }

  // Partial sort of order_[b, e) by key(i) = col[order_[i] * dim]: afterwards order_[mid] has rank
  // mid - b, keys before it are <= and keys after it are >= (the contract of std::nth_element,
  // which it replaces: that one's partition branches are mispredicted about half the time).
  // Quickselect with a median-of-three pivot and branch-free three-way partition passes (< p,
  // == p, > p), so runs of equal keys cannot stall it; short ranges end in an insertion sort.
  // Any such split gives the same kNN results: the tree only prunes, with exact bounds.
  void select_rank(const double* col, std::uint32_t b, std::uint32_t mid, std::uint32_t e) {
    const std::size_t d = dim();
    std::uint32_t* o = order_.data();
    auto key = [&](std::uint32_t i) { return col[static_cast<std::size_t>(o[i]) * d]; };
    // Moves the entries of [lo, hi) whose key satisfies pred to the front; returns their end.
    auto partition = [&](std::uint32_t lo, std::uint32_t hi, auto pred) {
      std::uint32_t j = lo;
      for (std::uint32_t i = lo; i < hi; ++i) {
        const std::uint32_t v = o[i];
        const bool take = pred(col[static_cast<std::size_t>(v) * d]);
        o[i] = o[j];
        o[j] = v;
        j += static_cast<std::uint32_t>(take);
      }
      return j;
    };
    std::uint32_t lo = b;
    std::uint32_t hi = e;
    while (hi - lo > 16) {
      const double k0 = key(lo);
      const double k1 = key(lo + (hi - lo) / 2);
      const double k2 = key(hi - 1);
      const double p = std::max(std::min(k0, k1), std::min(std::max(k0, k1), k2));
      const std::uint32_t lt = partition(lo, hi, [p](double x) { return x < p; });
      const std::uint32_t le = partition(lt, hi, [p](double x) { return x == p; });
      if (mid < lt) {
        hi = lt;
      } else if (mid < le) {
        return;  // every key in [lt, le) equals p
      } else {
        lo = le;
      }
    }
    for (std::uint32_t i = lo + 1; i < hi; ++i) {  // insertion sort of the short rest
      const std::uint32_t v = o[i];
      const double kv = col[static_cast<std::size_t>(v) * d];
      std::uint32_t j = i;
      while (j > lo && key(j - 1) > kv) {
        o[j] = o[j - 1];
        --j;
      }
      o[j] = v;
    }
  }

  [[nodiscard]] double box_dist2(const double* q, std::size_t node) const {
    const std::size_t d = dim();
    const double* lo = lo_.data() + node * d;
    const double* hi = hi_.data() + node * d;
    double s = 0.0;
    for (std::size_t j = 0; j < d; ++j) {
      const double a = lo[j] - q[j];
      const double b = q[j] - hi[j];
      const double g = gap(a, b);
      s += no_contract(g * g);
    }
    return s;
  }

  // k+1 nearest of tree position s (in leaf `leaf`) into bd/bi, ascending; returns the count.
  std::size_t query(std::uint32_t s, std::uint32_t leaf, std::size_t kk, double* bd,
                    std::uint32_t* bi) const {
    const std::size_t d = dim();
    const double* q = pts_.data() + static_cast<std::size_t>(s) * d;
    std::size_t cnt = 0;
    double worst = std::numeric_limits<double>::infinity();
    auto scan = [&](const Node& nd) {
      for (auto t = nd.begin; t < nd.end; ++t) {
        const double d2 = sq_dist_seq(q, pts_.data() + static_cast<std::size_t>(t) * d, d);
        if (d2 > worst) continue;
        const std::uint32_t id = order_[t];
        if (cnt == kk && d2 == worst && id > bi[kk - 1]) continue;
        std::size_t pos = cnt < kk ? cnt++ : kk - 1;
        while (pos > 0 && (bd[pos - 1] > d2 || (bd[pos - 1] == d2 && bi[pos - 1] > id))) {
          bd[pos] = bd[pos - 1];
          bi[pos] = bi[pos - 1];
          --pos;
        }
        bd[pos] = d2;
        bi[pos] = id;
        if (cnt == kk) worst = bd[kk - 1];
      }
    };
    scan(nodes_[leaf]);
    struct Entry {
      std::uint32_t node;
      double box2;
    };
    Entry stack[128];
    int top = 0;
    stack[top++] = {0, 0.0};
    while (top > 0) {
      const Entry en = stack[--top];
      if (en.box2 > worst || en.node == leaf) continue;
      const Node& nd = nodes_[en.node];
      if (nd.left < 0) {
        scan(nd);
        continue;
      }
      const auto l = static_cast<std::uint32_t>(nd.left);
      const auto r = static_cast<std::uint32_t>(nd.right);
      const Entry el{l, box_dist2(q, l)};
      const Entry er{r, box_dist2(q, r)};
      if (el.box2 <= er.box2) {  // nearer child on top
        if (er.box2 <= worst) stack[top++] = er;
        if (el.box2 <= worst) stack[top++] = el;
      } else {
        if (el.box2 <= worst) stack[top++] = el;
        if (er.box2 <= worst) stack[top++] = er;
      }
    }
    return cnt;
  }

  // Squared distances from q to the kLeafSize tree positions from b (the padding of soa_ makes
  // reading past a leaf's end safe; such lanes are masked by the caller): one fixed-length pass
  // per dimension over contiguous coordinates, so the compiler vectorises and unrolls it; each
  // lane sums its squares in dimension order exactly like sq_dist_seq.
  void leaf_sq_dists(const double* q, std::uint32_t b, double* out) const {
    const std::size_t d = dim();
    {
      const double* x = soa_.data() + b;
      const double q0 = q[0];
      for (std::uint32_t t = 0; t < kLeafSize; ++t) {
        const double g = x[t] - q0;
        out[t] = no_contract(g * g);
      }
    }
    for (std::size_t j = 1; j < d; ++j) {
      const double* x = soa_.data() + j * stride_ + b;
      const double qj = q[j];
      for (std::uint32_t t = 0; t < kLeafSize; ++t) {
        const double g = x[t] - qj;
        out[t] += no_contract(g * g);
      }
    }
  }

  // leaf_sq_dists into buf, and a bit mask of the lanes strictly below worst. For D = 3 on AVX2
  // targets one 4-lane vector per dimension step: each lane still sums its squares in dimension
  // order with separate roundings (no FMA), so buf is bitwise that of leaf_sq_dists.
  std::uint32_t leaf_block_below(const double* q, std::uint32_t b, double worst,
                                 double* buf) const {
#if defined(__AVX2__)
    if constexpr (kDim == 3) {
      const double* xs = soa_.data() + b;
      const double* ys = xs + stride_;
      const double* zs = ys + stride_;
      const __m256d qx = _mm256_set1_pd(q[0]);
      const __m256d qy = _mm256_set1_pd(q[1]);
      const __m256d qz = _mm256_set1_pd(q[2]);
      const __m256d w = _mm256_set1_pd(worst);
      std::uint32_t bits = 0;
      for (std::uint32_t v = 0; v < kLeafSize; v += 4) {
        const __m256d dx = _mm256_sub_pd(_mm256_loadu_pd(xs + v), qx);
        const __m256d dy = _mm256_sub_pd(_mm256_loadu_pd(ys + v), qy);
        const __m256d dz = _mm256_sub_pd(_mm256_loadu_pd(zs + v), qz);
        __m256d d2 = no_contract_simd(_mm256_mul_pd(dx, dx));
        d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dy, dy)));
        d2 = _mm256_add_pd(d2, no_contract_simd(_mm256_mul_pd(dz, dz)));
        _mm256_storeu_pd(buf + v, d2);
        bits |= static_cast<std::uint32_t>(_mm256_movemask_pd(_mm256_cmp_pd(d2, w, _CMP_LT_OQ)))
                << v;
      }
      return bits;
    }
#endif
    leaf_sq_dists(q, b, buf);
    std::uint32_t bits = 0;
    for (std::uint32_t t = 0; t < kLeafSize; ++t) {
      bits |= static_cast<std::uint32_t>(buf[t] < worst) << t;
    }
    return bits;
  }

  // Offers the points of node nd to q's ascending list bd of the kk smallest squared distances
  // (+inf while not full); worst = bd[kk - 1]. Branch-light, as these branches are unpredictable:
  // a whole kLeafSize block of distances is compared with worst at once, and each hit is merged
  // by bd[i] = min(bd[i], max(bd[i-1], x)), a branch-free sorted insertion.
  void scan_core(const double* q, const Node& nd, std::size_t kk, double* bd, double& worst) const {
#if defined(__AVX2__)
    if constexpr (kDim == 3) {
      if (kk <= 4) return scan_core_avx2<1>(q, nd, kk, bd, worst);
      if (kk <= 8) return scan_core_avx2<2>(q, nd, kk, bd, worst);
      if (kk <= 12) return scan_core_avx2<3>(q, nd, kk, bd, worst);
      if (kk <= 16) return scan_core_avx2<4>(q, nd, kk, bd, worst);
    }
#endif
    double buf[kLeafSize];
    for (auto b = nd.begin; b < nd.end; b += kLeafSize) {
      const std::uint32_t len = std::min(kLeafSize, nd.end - b);
      std::uint32_t bits = leaf_block_below(q, b, worst, buf) & ((1U << len) - 1U);
      while (bits != 0U) {
        const auto t = static_cast<std::uint32_t>(std::countr_zero(bits));
        bits &= bits - 1U;
        const double x = buf[t];
        if (!(x < worst)) continue;  // cannot lower the (k+1)-th smallest
        for (std::size_t i = kk - 1; i > 0; --i) bd[i] = std::min(bd[i], std::max(bd[i - 1], x));
        bd[0] = std::min(bd[0], x);
        worst = bd[kk - 1];
      }
    }
  }

  // Length of one query's list in run_core_only: scan_core_avx2 keeps it in whole 4-lane vectors
  // (the slots past kk only hold further smallest values, so bd[kk - 1] is unchanged).
  [[nodiscard]] static std::size_t list_stride(std::size_t kk) {
#if defined(__AVX2__)
    if (kDim == 3 && kk <= 16) return (kk + 3) & ~std::size_t{3};
#endif
    return kk;
  }

#if defined(__AVX2__)
  // scan_core for D = 3 with the list held in kB 4-lane registers (4·kB >= kk slots, ascending).
  // The merge bd[i] = min(bd[i], max(bd[i-1], x)) runs on whole registers: bd[i-1] is the list
  // shifted up one lane (a lane permute plus the top lane of the register below; -inf below
  // slot 0). The same values as the scalar merge, so results are unchanged.
  template <int kB>
  void scan_core_avx2(const double* q, const Node& nd, std::size_t kk, double* bd,
                      double& worst) const {
    __m256d v[kB];
    for (int j = 0; j < kB; ++j) v[j] = _mm256_loadu_pd(bd + 4 * j);
    const int wl = static_cast<int>((kk - 1) & 3U);  // lane of slot kk - 1 in v[(kk - 1) / 4]
    const auto wb = static_cast<int>((kk - 1) / 4);
    const __m256d neg_inf = _mm256_set1_pd(-std::numeric_limits<double>::infinity());
    double buf[kLeafSize];
    for (auto b = nd.begin; b < nd.end; b += kLeafSize) {
      const std::uint32_t len = std::min(kLeafSize, nd.end - b);
      std::uint32_t bits = leaf_block_below(q, b, worst, buf) & ((1U << len) - 1U);
      while (bits != 0U) {
        const auto t = static_cast<std::uint32_t>(std::countr_zero(bits));
        bits &= bits - 1U;
        const double x = buf[t];
        if (!(x < worst)) continue;  // cannot lower the kk-th smallest
        const __m256d vx = _mm256_set1_pd(x);
        for (int j = kB - 1; j >= 0; --j) {
          const __m256d below =
              j > 0 ? _mm256_permute4x64_pd(v[j - 1], 0xFF) : neg_inf;  // slot 4j - 1
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
#endif

  // Squared distance between the boxes of nodes a and b, summed like sq_dist_seq: a lower bound
  // of every computed squared distance between a point of a and a point of b.
  [[nodiscard]] double box_box_dist2(std::size_t a, std::size_t b) const {
    const std::size_t d = dim();
    const double* alo = lo_.data() + a * d;
    const double* ahi = hi_.data() + a * d;
    const double* blo = lo_.data() + b * d;
    const double* bhi = hi_.data() + b * d;
    double s = 0.0;
    for (std::size_t j = 0; j < d; ++j) {
      const double x = blo[j] - ahi[j];
      const double y = alo[j] - bhi[j];
      const double g = gap(x, y);
      s += no_contract(g * g);
    }
    return s;
  }

  std::size_t n_, dim_;
  std::vector<std::uint32_t> order_;  // tree position -> point id
  std::vector<double> pts_;           // coordinates in tree order
  std::vector<double> soa_;           // the same, per dimension: soa_[j * stride_ + s]
  std::size_t stride_ = 0;            // n_ + kLeafSize (zero padding)
  std::vector<Node> nodes_;
  std::vector<double> lo_, hi_;  // node boxes
};

inline std::vector<double> knn_core_distances(const DenseRowsNd& ds, std::size_t k, int num_threads,
                                              std::vector<std::uint32_t>* neighbors = nullptr) {
  std::vector<double> core;
  if (ds.n <= kSmallKnnMaxPoints && neighbors == nullptr) {
    if (ds.dim == 3) {
      KnnTreeSmall<3>(ds).run_core_only(k, num_threads, core);
    } else if (ds.dim == 2) {
      KnnTreeSmall<2>(ds).run_core_only(k, num_threads, core);
    } else {
      KnnTreeSmall<-1>(ds).run_core_only(k, num_threads, core);
    }
  } else if (ds.n <= kSmallKnnMaxPoints) {
    if (ds.dim == 3) {
      KnnTreeSmall<3>(ds).run(k, num_threads, core, neighbors);
    } else if (ds.dim == 2) {
      KnnTreeSmall<2>(ds).run(k, num_threads, core, neighbors);
    } else {
      KnnTreeSmall<-1>(ds).run(k, num_threads, core, neighbors);
    }
  } else if (ds.dim == 3) {
    knn_core_distances_impl<3>(ds, k, num_threads, core, neighbors);
  } else if (ds.dim == 2) {
    knn_core_distances_impl<2>(ds, k, num_threads, core, neighbors);
  } else {
    knn_core_distances_impl<-1>(ds, k, num_threads, core, neighbors);
  }
  return core;
}

}  // namespace ds3d::detail
