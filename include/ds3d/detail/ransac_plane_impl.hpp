// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::ransac_plane (included by ransac_plane.hpp). Not API.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>

#include "ds3d/detail/finite_points.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/preprocess/ransac_plane.hpp"

namespace ds3d {

inline void RansacPlaneParams::validate() const {
  const char* fn = "ds3d::ransac_plane";
  DS3D_CHECK(std::isfinite(distance_threshold) && distance_threshold > 0, fn,
             ": distance_threshold must be finite and > 0 (got ", distance_threshold, ")");
  DS3D_CHECK(max_iterations >= 1, fn, ": max_iterations must be >= 1 (got ", max_iterations, ")");
  DS3D_CHECK(confidence >= 0.0 && confidence <= 1.0, fn, ": confidence must be in [0, 1] (got ",
             confidence, ")");
  DS3D_CHECK(normal_prior.allFinite(), fn, ": normal_prior must be finite (got ", normal_prior.x(),
             ", ", normal_prior.y(), ", ", normal_prior.z(), ")");
  DS3D_CHECK(max_angle_deg > 0.0 && max_angle_deg <= 90.0, fn,
             ": max_angle_deg must be in (0, 90] (got ", max_angle_deg, ")");
  (void)detail::resolve_num_threads(num_threads, fn);
}

namespace detail {

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny seedable generator, enough to draw triples.
struct SplitMix64 {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31U);
  }
};

/// Number of |n·p + d| < t among SoA points, in float (the scoring hot loop; vectorises).
inline std::uint32_t count_plane_inliers(const float* x, const float* y, const float* z,
                                         std::size_t n, float a, float b, float c, float d,
                                         float t) {
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float dist = a * x[i] + b * y[i] + c * z[i] + d;
    count += std::abs(dist) < t ? 1U : 0U;
  }
  return count;
}

/// The finite points relative to their centroid, as float SoA: scoring runs in float on these,
/// so that far-away clouds keep their precision.
struct CentredPoints {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  std::vector<float> xs, ys, zs;
};

inline CentredPoints centre_points(const FinitePoints& f) {
  const std::size_t n = f.size();
  CentredPoints c;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) centre += Eigen::Vector3d(f.x[i], f.y[i], f.z[i]);
  centre /= static_cast<double>(n);
  c.centre = centre;
  c.xs.resize(n);
  c.ys.resize(n);
  c.zs.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    c.xs[i] = static_cast<float>(f.x[i] - centre.x());
    c.ys[i] = static_cast<float>(f.y[i] - centre.y());
    c.zs[i] = static_cast<float>(f.z[i] - centre.z());
  }
  return c;
}

/// The normal prior of RansacPlaneParams, resolved once.
struct PlanePrior {
  bool use_prior = false;
  Eigen::Vector3d up = Eigen::Vector3d::Zero();  ///< unit prior, zero without one
  double cos_tol = 0.0;                          ///< cos(max_angle_deg)
  bool origin_above = false;                     ///< origin must lie on the +up side
};

inline PlanePrior plane_prior(const RansacPlaneParams& params) {
  PlanePrior p;
  p.use_prior = params.normal_prior.squaredNorm() > 0.0;
  p.up = p.use_prior ? params.normal_prior.normalized() : Eigen::Vector3d::Zero();
  p.cos_tol = std::cos(params.max_angle_deg * 3.14159265358979323846 / 180.0);
  p.origin_above = p.use_prior && params.origin_above;
  return p;
}

/// Seeded plane hypotheses from triples of the centred points: each iteration's triple depends
/// only on (seed, iteration), so any batching scores the same hypotheses.
struct PlaneSampler {
  const CentredPoints& c;
  const PlanePrior& prior;
  std::uint64_t seed;

  /// Signed side of the origin for a plane in the centred frame (origin is at -centre there).
  [[nodiscard]] bool origin_on_up_side(const Eigen::Vector4d& pl_centred) const {
    const double side = -pl_centred.head<3>().dot(c.centre) + pl_centred[3];
    return (pl_centred.head<3>().dot(prior.up) >= 0.0 ? side : -side) > 0.0;
  }

  /// Hypothesis of iteration `it`, in the centred frame; false when degenerate or off-prior.
  bool hypothesis(std::uint32_t it, Eigen::Vector4d& plane) const {
    const std::vector<float>& xs = c.xs;
    const std::vector<float>& ys = c.ys;
    const std::vector<float>& zs = c.zs;
    SplitMix64 rng{seed ^ (0xD1B54A32D192ED03ULL * (std::uint64_t{it} + 1))};
    const auto nn = static_cast<std::uint64_t>(xs.size());
    const auto i0 = static_cast<std::size_t>(rng.next() % nn);
    auto i1 = static_cast<std::size_t>(rng.next() % (nn - 1));
    i1 += i1 >= i0 ? 1 : 0;
    auto i2 = static_cast<std::size_t>(rng.next() % (nn - 2));
    const std::size_t lo = std::min(i0, i1);
    const std::size_t hi = std::max(i0, i1);
    i2 += i2 >= lo ? 1 : 0;
    i2 += i2 >= hi ? 1 : 0;
    const Eigen::Vector3d p0(xs[i0], ys[i0], zs[i0]);
    const Eigen::Vector3d e1 = Eigen::Vector3d(xs[i1], ys[i1], zs[i1]) - p0;
    const Eigen::Vector3d e2 = Eigen::Vector3d(xs[i2], ys[i2], zs[i2]) - p0;
    Eigen::Vector3d normal = e1.cross(e2);
    const double len = normal.norm();
    if (!(len > 1e-12 * e1.norm() * e2.norm()) || !(len > 0.0)) return false;
    normal /= len;
    if (prior.use_prior && std::abs(normal.dot(prior.up)) < prior.cos_tol) return false;
    plane << normal, -normal.dot(p0);
    if (prior.origin_above && !origin_on_up_side(plane)) return false;
    return true;
  }
};

/// The best hypothesis of the search: its iteration and inlier count (-1: none was valid).
struct RansacBest {
  std::int64_t count = -1;
  std::uint32_t it = 0;
};

/// Scores hypotheses in batches (in parallel for large clouds) and reduces them in iteration
/// order, stopping early at the confidence bound; sets r.iterations.
inline RansacBest search_planes(const PlaneSampler& sampler, const RansacPlaneParams& params,
                                int threads, RansacPlaneResult& r) {
  const CentredPoints& c = sampler.c;
  const std::size_t n = c.xs.size();
  const auto tf = static_cast<float>(params.distance_threshold);
  const std::uint32_t max_it = params.max_iterations;
  // Threads are started per batch of hypotheses: below kRansacParallelMinPoints a batch scores
  // faster than its threads start, so small clouds run serially (same output either way).
  const int workers = n < kRansacParallelMinPoints ? 1 : threads;
  const std::size_t batch = workers == 1 ? 1 : static_cast<std::size_t>(workers) * 8;
  std::vector<std::int64_t> scores(batch);
  RansacBest best;
  double needed = static_cast<double>(max_it);
  std::uint32_t it = 0;
  bool stop = false;
  while (!stop && it < max_it) {
    const std::size_t nb = std::min<std::size_t>(batch, max_it - it);
    parallel_chunks(nb, nb, workers, [&](std::size_t b, std::size_t e, std::size_t) {
      for (std::size_t k = b; k < e; ++k) {
        Eigen::Vector4d pl;
        if (!sampler.hypothesis(it + static_cast<std::uint32_t>(k), pl)) {
          scores[k] = -1;
          continue;
        }
        scores[k] = count_plane_inliers(c.xs.data(), c.ys.data(), c.zs.data(), n,
                                        static_cast<float>(pl[0]), static_cast<float>(pl[1]),
                                        static_cast<float>(pl[2]), static_cast<float>(pl[3]), tf);
      }
    });
    // Reduce in iteration order: identical to a serial run whatever the batch size.
    for (std::size_t k = 0; k < nb; ++k) {
      const std::uint32_t cur = it + static_cast<std::uint32_t>(k);
      r.iterations = cur + 1;
      if (scores[k] > best.count) {
        best.count = scores[k];
        best.it = cur;
        if (params.confidence < 1.0 && best.count > 0) {
          const double w = static_cast<double>(best.count) / static_cast<double>(n);
          const double p_fail = 1.0 - w * w * w;
          needed = p_fail <= 0.0 ? 1.0 : std::log(1.0 - params.confidence) / std::log(p_fail);
        }
      }
      if (static_cast<double>(r.iterations) >= needed) {
        stop = true;
        break;
      }
    }
    it += static_cast<std::uint32_t>(nb);
  }
  return best;
}

/// Positions (into `f`) of the points with |pl·(p, 1)| < band, in double on the original
/// coordinates.
inline void select_plane_points(const FinitePoints& f, const Eigen::Vector4d& pl, double band,
                                std::vector<std::uint32_t>& pos) {
  const std::size_t n = f.size();
  pos.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const double dist = pl[0] * f.x[i] + pl[1] * f.y[i] + pl[2] * f.z[i] + pl[3];
    if (std::abs(dist) < band) pos.push_back(static_cast<std::uint32_t>(i));
  }
}

/// Local optimisation (LO-RANSAC, Chum, Matas & Kittler 2003; iterated least squares as in
/// LO+, Lebeda, Matas & Chum 2012): fit the points within kRefineBand * t of the current plane
/// by least squares (smallest eigenvector of their covariance), re-select the inliers (< t) and
/// keep the round only if it does not lose inliers; stop when a round changes nothing.
/// Fitting the < t inliers alone (the earlier version) is biased towards the current plane
/// when the noise is not small against t: on the 1M-point room frame (back wall at 4.6 m)
/// each such round recovered only ~0.3 % of the inliers, 3 rounds ending 2.9 % below PCL's
/// plane; with the 3t band the first round recovers most of the tilt.
/// `plane` (original frame) and its inliers `inl` are updated in place.
inline void refine_plane(const FinitePoints& f, const CentredPoints& c, const PlanePrior& prior,
                         const RansacPlaneParams& params, Eigen::Vector4d& plane,
                         std::vector<std::uint32_t>& inl) {
  const std::vector<float>& xs = c.xs;
  const std::vector<float>& ys = c.ys;
  const std::vector<float>& zs = c.zs;
  const double t = params.distance_threshold;
  constexpr double kRefineBand = 3.0;
  std::vector<std::uint32_t> cand;
  std::vector<std::uint32_t> band;
  for (std::uint32_t round = 0; round < params.refine_iterations && inl.size() >= 3; ++round) {
    select_plane_points(f, plane, kRefineBand * t, band);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const std::uint32_t i : band) mean += Eigen::Vector3d(xs[i], ys[i], zs[i]);
    mean /= static_cast<double>(band.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const std::uint32_t i : band) {
      const Eigen::Vector3d q = Eigen::Vector3d(xs[i], ys[i], zs[i]) - mean;
      cov.noalias() += q * q.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    if (es.info() != Eigen::Success) break;
    const Eigen::Vector3d normal = es.eigenvectors().col(0).normalized();
    if (!normal.allFinite()) break;
    if (prior.use_prior && std::abs(normal.dot(prior.up)) < prior.cos_tol) break;
    Eigen::Vector4d refit;
    refit << normal, -normal.dot(mean + c.centre);
    if (prior.origin_above && (normal.dot(prior.up) >= 0.0 ? refit[3] : -refit[3]) <= 0.0) break;
    select_plane_points(f, refit, t, cand);
    if (cand.size() < inl.size()) break;
    const bool same = cand == inl;
    plane = refit;
    inl.swap(cand);
    if (same) break;
  }
}

/// Fills the result: the plane with its sign convention (along the prior, else the
/// largest-magnitude normal component positive) and the inliers as input indices.
inline void finish_plane(const FinitePoints& f, const PlanePrior& prior,
                         const Eigen::Vector4d& plane, const std::vector<std::uint32_t>& inl,
                         RansacPlaneResult& r) {
  double s = 1.0;
  if (prior.use_prior) {
    s = plane.head<3>().dot(prior.up) < 0.0 ? -1.0 : 1.0;
  } else {
    Eigen::Index k = 0;
    plane.head<3>().cwiseAbs().maxCoeff(&k);
    s = plane[k] < 0.0 ? -1.0 : 1.0;
  }
  r.plane = s * plane;
  r.found = true;
  r.inliers.reserve(inl.size());
  for (const std::uint32_t i : inl) r.inliers.push_back(f.index[i]);
}

}  // namespace detail

template <PointCloud C>
RansacPlaneResult ransac_plane(const C& cloud, const RansacPlaneParams& params) {
  constexpr const char* kFn = "ds3d::ransac_plane";
  params.validate();
  const int threads = detail::resolve_num_threads(params.num_threads, kFn);
  const detail::FinitePoints f = detail::gather_finite(cloud, params.on_non_finite, kFn);
  RansacPlaneResult r;
  r.num_non_finite = f.num_non_finite;
  if (f.size() < 3) return r;

  // The final selection is done in double on the original coordinates.
  const detail::CentredPoints c = detail::centre_points(f);
  const detail::PlanePrior prior = detail::plane_prior(params);
  const detail::PlaneSampler sampler{c, prior, params.seed};
  const detail::RansacBest best = detail::search_planes(sampler, params, threads, r);
  if (best.count < 0) return r;

  // Plane in the original frame: n·(p - centre) + d_c = n·p + (d_c - n·centre).
  Eigen::Vector4d plane;
  (void)sampler.hypothesis(best.it, plane);
  plane[3] -= plane.head<3>().dot(c.centre);
  std::vector<std::uint32_t> inl;
  detail::select_plane_points(f, plane, params.distance_threshold, inl);
  detail::refine_plane(f, c, prior, params, plane, inl);
  detail::finish_plane(f, prior, plane, inl, r);
  return r;
}

}  // namespace ds3d
