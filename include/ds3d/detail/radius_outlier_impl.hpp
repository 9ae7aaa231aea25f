// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::remove_radius_outliers (included by radius_outlier.hpp). Not API.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "ds3d/detail/kdtree.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/preprocess/radius_outlier.hpp"

namespace ds3d {

inline void RadiusOutlierParams::validate() const {
  const char* fn = "ds3d::remove_radius_outliers";
  DS3D_CHECK(std::isfinite(radius) && radius > 0, fn, ": radius must be finite and > 0 (got ",
             radius, ")");
  DS3D_CHECK(search == RadiusSearch::kGrid || search == RadiusSearch::kKdTree, fn,
             ": search must be kGrid or kKdTree (got ", static_cast<int>(search), ")");
  (void)detail::resolve_num_threads(num_threads, fn);
}

namespace detail {

/// Position of the first cell whose key is >= (x, y, z) (lexicographic lower bound).
inline std::size_t find_cell(const VoxelSort& s, std::int64_t x, std::int64_t y, std::int64_t z) {
  const std::array<std::int64_t, 3> key{x, y, z};
  return static_cast<std::size_t>(std::lower_bound(s.cell_key.begin(), s.cell_key.end(), key) -
                                  s.cell_key.begin());
}

/// RadiusSearch::kKdTree: nanoflann radius search per finite point, exact double test, early
/// exit at k accepted neighbours.
template <PointCloud C>
RadiusOutlierResult radius_outliers_kdtree(const C& cloud, const RadiusOutlierParams& params,
                                           int threads, const char* function) {
  RadiusOutlierResult r;
  const std::size_t n_all = cloud::size(cloud);
  DS3D_CHECK(n_all < std::numeric_limits<std::uint32_t>::max(), function,
             ": clouds are limited to 2^32 - 1 points (got ", n_all, ")");
  std::vector<std::uint32_t> finite;
  finite.reserve(n_all);
  double max_abs = 0;
  for (std::size_t i = 0; i < n_all; ++i) {
    const Eigen::Vector3f p = cloud::point(cloud, i);
    if (!cloud::is_finite(p)) {
      DS3D_CHECK(params.on_non_finite != NonFinite::kThrow, function, ": point ", i,
                 " is not finite (", p.x(), ", ", p.y(), ", ", p.z(), ")");
      ++r.num_non_finite;
      continue;
    }
    finite.push_back(static_cast<std::uint32_t>(i));
    max_abs = std::max(max_abs, static_cast<double>(p.cwiseAbs().maxCoeff()));
  }
  if (params.min_neighbors == 0 || finite.empty()) {
    if (params.min_neighbors == 0) r.kept = finite;
    return r;
  }
  const KdTreeCloudAdaptor<C> adaptor{cloud, &finite};
  KdTree3f<C> tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  tree.buildIndex();
  const double r2 = params.radius * params.radius;
  // nanoflann prunes with float coordinate differences: widen its radius by far more than their
  // rounding error (2^-23 relative to the coordinates), then decide each candidate exactly.
  const double slack = params.radius * 1e-4 + max_abs * 1e-5;
  const double search_r2 = (params.radius + slack) * (params.radius + slack);
  const std::uint32_t k_min = params.min_neighbors;
  std::vector<std::uint8_t> keep(finite.size(), 0);
  parallel_chunks(finite.size(), static_cast<std::size_t>(threads) * 8, threads,
                  [&](std::size_t b, std::size_t e, std::size_t) {
                    for (std::size_t t = b; t < e; ++t) {
                      const Eigen::Vector3f q = cloud::point(cloud, finite[t]);
                      const double qx = q.x();
                      const double qy = q.y();
                      const double qz = q.z();
                      auto accept = [&](std::uint32_t j) {
                        if (j == t) return false;  // the point itself
                        const Eigen::Vector3f p = cloud::point(cloud, finite[j]);
                        const double dx = qx - static_cast<double>(p.x());
                        const double dy = qy - static_cast<double>(p.y());
                        const double dz = qz - static_cast<double>(p.z());
                        return dx * dx + dy * dy + dz * dz <= r2;
                      };
                      CountingRadiusResultSet<decltype(accept)> rs(search_r2, k_min, accept);
                      const std::array<float, 3> qv{q.x(), q.y(), q.z()};
                      tree.findNeighbors(rs, qv.data(), nanoflann::SearchParams());
                      keep[t] = rs.count() >= k_min ? 1 : 0;
                    }
                  });
  for (std::size_t t = 0; t < finite.size(); ++t) {
    if (keep[t] != 0) r.kept.push_back(finite[t]);
  }
  return r;
}

}  // namespace detail

template <PointCloud C>
RadiusOutlierResult remove_radius_outliers(const C& cloud, const RadiusOutlierParams& params) {
  constexpr const char* kFn = "ds3d::remove_radius_outliers";
  params.validate();
  const int threads = detail::resolve_num_threads(params.num_threads, kFn);
  if (params.search == RadiusSearch::kKdTree) {
    return detail::radius_outliers_kdtree(cloud, params, threads, kFn);
  }
  RadiusOutlierResult r;
  // Cells slightly larger than R: with |x_i - x_j| <= R, the rounded quotients x/h then differ by
  // at most 1 as long as |x/h| < 2^31 (relative rounding error 2^-52 against a 1e-6 margin), so
  // every neighbour lies in the 27 surrounding cells.
  const double h = params.radius * (1.0 + 1e-6);
  const detail::VoxelSort s =
      detail::sort_by_voxel(cloud, {h, h, h}, params.on_non_finite, threads, kFn);
  r.num_non_finite = s.num_non_finite;
  const std::size_t n = s.index.size();
  if (params.min_neighbors == 0) {
    for (std::size_t i = 0; i < cloud::size(cloud); ++i) {
      if (cloud::is_finite(cloud::point(cloud, i))) r.kept.push_back(static_cast<std::uint32_t>(i));
    }
    return r;
  }
  if (n == 0) return r;
  const std::size_t num_cells = s.num_cells();
  for (const auto& ck : s.cell_key) {
    for (const std::int64_t k : ck) {
      DS3D_CHECK(k > -2147483648LL && k < 2147483647LL, kFn,
                 ": the cloud spans more than 2^31 grid cells of the radius ", params.radius,
                 " (grid index ", k, ")");
    }
  }

  // Points in cell order (SoA) so that each cell is one contiguous range.
  std::vector<float> xs(n), ys(n), zs(n);
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3f p = cloud::point(cloud, s.index[k]);
    xs[k] = p.x();
    ys[k] = p.y();
    zs[k] = p.z();
  }
  const double r2 = params.radius * params.radius;
  const std::uint32_t k_min = params.min_neighbors;
  std::vector<std::uint8_t> keep(n, 0);  // by sorted position

  detail::parallel_chunks(
      num_cells, static_cast<std::size_t>(threads) * 8, threads,
      [&](std::size_t cb, std::size_t ce, std::size_t) {
        std::vector<std::array<std::uint32_t, 2>> ranges;
        ranges.reserve(27);
        for (std::size_t c = cb; c < ce; ++c) {
          const std::uint32_t lo = s.cell_begin[c];
          const std::uint32_t hi = s.cell_begin[c + 1];
          const std::int64_t cx = s.cell_key[c][0];
          const std::int64_t cy = s.cell_key[c][1];
          const std::int64_t cz = s.cell_key[c][2];
          ranges.clear();
          ranges.push_back({lo, hi});  // own cell first: dense surfaces exit early there
          for (std::int64_t dx = -1; dx <= 1; ++dx) {
            for (std::int64_t dy = -1; dy <= 1; ++dy) {
              // Cells (cx+dx, cy+dy, cz-1..cz+1) are consecutive in lexicographic order.
              std::size_t q = detail::find_cell(s, cx + dx, cy + dy, cz - 1);
              for (; q < num_cells; ++q) {
                const auto& kq = s.cell_key[q];
                if (kq[0] != cx + dx || kq[1] != cy + dy || kq[2] > cz + 1) break;
                if (q != c) ranges.push_back({s.cell_begin[q], s.cell_begin[q + 1]});
              }
            }
          }
          std::uint32_t total = 0;
          for (const auto& rg : ranges) total += rg[1] - rg[0];
          if (total < k_min + 1) continue;  // not enough candidates (the point itself is one)
          for (std::uint32_t i = lo; i < hi; ++i) {
            const double xi = xs[i];
            const double yi = ys[i];
            const double zi = zs[i];
            std::uint32_t count = 0;
            for (const auto& rg : ranges) {
              for (std::uint32_t j = rg[0]; j < rg[1]; ++j) {
                const double ddx = xi - static_cast<double>(xs[j]);
                const double ddy = yi - static_cast<double>(ys[j]);
                const double ddz = zi - static_cast<double>(zs[j]);
                count += (ddx * ddx + ddy * ddy + ddz * ddz <= r2) ? 1U : 0U;
              }
              if (rg[0] == lo) count -= 1;  // the point itself (distance 0) was counted
              if (count >= k_min) break;
            }
            keep[i] = count >= k_min ? 1 : 0;
          }
        }
      });

  // Back to input order without a sort: a flag per input point.
  std::vector<std::uint8_t> keep_input(cloud::size(cloud), 0);
  for (std::size_t k = 0; k < n; ++k) keep_input[s.index[k]] = keep[k];
  for (std::size_t i = 0; i < keep_input.size(); ++i) {
    if (keep_input[i] != 0) r.kept.push_back(static_cast<std::uint32_t>(i));
  }
  return r;
}

}  // namespace ds3d
