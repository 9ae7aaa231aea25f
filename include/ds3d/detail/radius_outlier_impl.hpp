// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::remove_radius_outliers (included by radius_outlier.hpp). Not API.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/radius_outlier.hpp"

namespace ds3d {

inline void RadiusOutlierParams::validate() const {
  const char* fn = "ds3d::remove_radius_outliers";
  DS3D_CHECK(std::isfinite(radius) && radius > 0, fn, ": radius must be finite and > 0 (got ",
             radius, ")");
  (void)detail::resolve_num_threads(num_threads, fn);
}

namespace detail {

/// Lexicographic position of key (x, y, z) among the distinct cells of `s` (lower bound).
inline std::size_t find_cell(const SortedKeys& s, std::int64_t x, std::int64_t y, std::int64_t z) {
  std::size_t lo = 0;
  std::size_t hi = s.cell_begin.size() - 1;
  while (lo < hi) {
    const std::size_t mid = (lo + hi) / 2;
    const std::uint32_t p = s.order[s.cell_begin[mid]];
    const bool less = s.ix[p] != x ? s.ix[p] < x : (s.iy[p] != y ? s.iy[p] < y : s.iz[p] < z);
    if (less) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return lo;
}

}  // namespace detail

template <PointCloud C>
RadiusOutlierResult remove_radius_outliers(const C& cloud, const RadiusOutlierParams& params) {
  constexpr const char* kFn = "ds3d::remove_radius_outliers";
  params.validate();
  const int threads = detail::resolve_num_threads(params.num_threads, kFn);
  const detail::FinitePoints f = detail::gather_finite(cloud, params.on_non_finite, kFn);
  RadiusOutlierResult r;
  r.num_non_finite = f.num_non_finite;
  const std::size_t n = f.size();
  if (params.min_neighbors == 0) {
    r.kept = f.index;
    return r;
  }
  if (n == 0) return r;

  // Cells slightly larger than R: with |x_i - x_j| <= R, the rounded quotients x/h then differ by
  // at most 1 as long as |x/h| < 2^31 (relative rounding error 2^-52 against a 1e-6 margin), so
  // every neighbour lies in the 27 surrounding cells.
  const double h = params.radius * (1.0 + 1e-6);
  float amax = 0.0F;
  for (std::size_t i = 0; i < n; ++i) {
    amax = std::max({amax, std::abs(f.x[i]), std::abs(f.y[i]), std::abs(f.z[i])});
  }
  DS3D_CHECK(static_cast<double>(amax) / h < 2147483648.0, kFn,
             ": coordinate magnitude ", amax, " divided by radius ", params.radius,
             " exceeds 2^31 grid cells");
  const detail::SortedKeys s = detail::sort_by_voxel(f, {h, h, h}, threads, kFn);
  const std::size_t num_cells = s.cell_begin.size() - 1;

  // Points in cell order (SoA) so that each cell is one contiguous range.
  std::vector<float> xs(n), ys(n), zs(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t p = s.order[k];
    xs[k] = f.x[p];
    ys[k] = f.y[p];
    zs[k] = f.z[p];
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
          const std::uint32_t p0 = s.order[lo];
          const std::int64_t cx = s.ix[p0];
          const std::int64_t cy = s.iy[p0];
          const std::int64_t cz = s.iz[p0];
          ranges.clear();
          ranges.push_back({lo, hi});  // own cell first: dense surfaces exit early there
          for (std::int64_t dx = -1; dx <= 1; ++dx) {
            for (std::int64_t dy = -1; dy <= 1; ++dy) {
              // Cells (cx+dx, cy+dy, cz-1..cz+1) are consecutive in lexicographic order.
              std::size_t q = detail::find_cell(s, cx + dx, cy + dy, cz - 1);
              for (; q < num_cells; ++q) {
                const std::uint32_t p = s.order[s.cell_begin[q]];
                if (s.ix[p] != cx + dx || s.iy[p] != cy + dy || s.iz[p] > cz + 1) break;
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

  std::vector<std::uint8_t> keep_input(n, 0);  // by position in FinitePoints
  for (std::size_t k = 0; k < n; ++k) keep_input[s.order[k]] = keep[k];
  for (std::size_t i = 0; i < n; ++i) {
    if (keep_input[i] != 0) r.kept.push_back(f.index[i]);
  }
  return r;
}

}  // namespace ds3d
