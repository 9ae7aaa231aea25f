// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The selection steps of the forward pass: FPS, ball query, 3-NN. They use the same float32
// expressions as python/ds3d/htx/ops.py, so that the sampling indices are bit-identical.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "sparse_detector_impl.hpp"

namespace ds3d::detail::htx {

// FPS of k indices over rows of p (spec §3.2); float32 expressions identical to ops.py.
// Non-candidates (padding) carry distance -1 forever: min(-1, d2) = -1 never beats best_d = -1.
DS3D_NO_FP_CONTRACT std::vector<std::int32_t> farthest_point_sample(const Mat& p, Eigen::Index k,
                                                                    float padding_norm2) {
  const Eigen::Index n = p.rows();
  std::vector<std::int32_t> out(static_cast<std::size_t>(k), 0);
  if (n == 0 || k == 0) return out;
  const Eigen::ArrayXf x = p.col(0), y = p.col(1), z = p.col(2);  // structure of arrays
  Eigen::ArrayXf dist(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    const float xx = x[j] * x[j], yy = y[j] * y[j], zz = z[j] * z[j];
    dist[j] = (xx + yy) + zz > padding_norm2 ? 1e10F : -1.0F;
  }
  Eigen::Index last = 0;
  const float* px = x.data();
  const float* py = y.data();
  const float* pz = z.data();
  float* pd = dist.data();
  for (Eigen::Index i = 1; i < k; ++i) {
    const float lx = px[last], ly = py[last], lz = pz[last];
    for (Eigen::Index j = 0; j < n; ++j) {  // branch-free: vectorised (blend, no FMA)
      const float dx = px[j] - lx, dy = py[j] - ly, dz = pz[j] - lz;
      const float xx = dx * dx, yy = dy * dy, zz = dz * dz;
      const float d2 = (xx + yy) + zz;
      pd[j] = d2 < pd[j] ? d2 : pd[j];
    }
    const float best_d = std::max(-1.0F, dist.maxCoeff());  // Eigen's vectorised reduction
    Eigen::Index best = 0;
    if (best_d >= 0.0F) {
      while (pd[best] != best_d) ++best;  // lowest index holding the maximum
    }
    last = best;
    out[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(best);
  }
  return out;
}

// Ball query "first s by index" (strict <) around every centre: the offsets / r of the distinct
// samples, group i in rows [begin[i], begin[i+1]). The reference repeats the first index in empty
// slots; a repeated row cannot change a max-pool, so only distinct samples are returned.
// Candidates come from a uniform grid of cell size slightly above r (27 cells per centre, each
// cell's points in index order); their distances use the reference's float expression, and the
// first s by index are kept, so the result equals the brute-force scan. Clouds whose bounding box
// would need a huge grid fall back to that scan.
DS3D_NO_FP_CONTRACT Mat ball_group(const Mat& p, const Mat& centres, float r, Eigen::Index s,
                                   std::vector<Eigen::Index>& begin) {
  const Eigen::Index t = centres.rows();
  const Eigen::Index n = p.rows();
  const float r2 = r * r;
  begin.assign(static_cast<std::size_t>(t) + 1, 0);
  Mat grouped(t * s, 3);
  Eigen::Index rows = 0;
  auto take = [&](Eigen::Index i, Eigen::Index j) {
    grouped.row(rows++) = (p.row(j) - centres.row(i)) / r;
  };
  const Eigen::RowVector3f lo = p.colwise().minCoeff();
  const Eigen::RowVector3f hi = p.colwise().maxCoeff();
  const float cell = r * 1.001F;  // margin against rounding in the cell index
  Eigen::Array3i dims;
  double num_cells = 1.0;
  for (int a = 0; a < 3; ++a) {
    const double cells = std::floor(static_cast<double>(hi[a] - lo[a]) / cell) + 1.0;
    dims[a] = static_cast<int>(std::min(cells, 1e6));
    num_cells *= cells;
  }
  if (num_cells > 4.0 * static_cast<double>(n) + 4096.0) {  // sparse outliers: brute force
    for (Eigen::Index i = 0; i < t; ++i) {
      const float cx = centres(i, 0), cy = centres(i, 1), cz = centres(i, 2);
      Eigen::Index found = 0;
      for (Eigen::Index j = 0; j < n && found < s; ++j) {
        const float dx = cx - p(j, 0), dy = cy - p(j, 1), dz = cz - p(j, 2);
        const float xx = dx * dx, yy = dy * dy, zz = dz * dz;
        if ((xx + yy) + zz < r2) {
          take(i, j);
          ++found;
        }
      }
      begin[static_cast<std::size_t>(i) + 1] = rows;
    }
    grouped.conservativeResize(rows, 3);
    return grouped;
  }
  auto cell_of = [&](float v, int a) {
    return std::clamp(static_cast<int>((v - lo[a]) / cell), 0, dims[a] - 1);
  };
  const auto total = static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]) *
                     static_cast<std::size_t>(dims[2]);
  // Counting sort of points by cell: stable, so every cell lists its points in index order.
  std::vector<std::int32_t> start(total + 1, 0);
  std::vector<std::int32_t> key(static_cast<std::size_t>(n));
  for (Eigen::Index j = 0; j < n; ++j) {
    const auto kx = static_cast<std::size_t>(cell_of(p(j, 0), 0));
    const auto ky = static_cast<std::size_t>(cell_of(p(j, 1), 1));
    const auto kz = static_cast<std::size_t>(cell_of(p(j, 2), 2));
    const std::size_t k =
        (kx * static_cast<std::size_t>(dims[1]) + ky) * static_cast<std::size_t>(dims[2]) + kz;
    key[static_cast<std::size_t>(j)] = static_cast<std::int32_t>(k);
    ++start[k + 1];
  }
  for (std::size_t k = 0; k < total; ++k) start[k + 1] += start[k];
  std::vector<std::int32_t> order(static_cast<std::size_t>(n));
  {
    std::vector<std::int32_t> fill(start.begin(), start.end() - 1);
    for (Eigen::Index j = 0; j < n; ++j) {
      order[static_cast<std::size_t>(
          fill[static_cast<std::size_t>(key[static_cast<std::size_t>(j)])]++)] =
          static_cast<std::int32_t>(j);
    }
  }
  std::vector<std::int32_t> cand;
  for (Eigen::Index i = 0; i < t; ++i) {
    const float cx = centres(i, 0), cy = centres(i, 1), cz = centres(i, 2);
    const int gx = cell_of(cx, 0), gy = cell_of(cy, 1), gz = cell_of(cz, 2);
    cand.clear();
    for (int x = std::max(gx - 1, 0); x <= std::min(gx + 1, dims[0] - 1); ++x) {
      for (int y = std::max(gy - 1, 0); y <= std::min(gy + 1, dims[1] - 1); ++y) {
        for (int z = std::max(gz - 1, 0); z <= std::min(gz + 1, dims[2] - 1); ++z) {
          const std::size_t k = (static_cast<std::size_t>(x) * static_cast<std::size_t>(dims[1]) +
                                 static_cast<std::size_t>(y)) *
                                    static_cast<std::size_t>(dims[2]) +
                                static_cast<std::size_t>(z);
          for (std::int32_t q = start[k]; q < start[k + 1]; ++q) {
            const std::int32_t j = order[static_cast<std::size_t>(q)];
            const float dx = cx - p(j, 0), dy = cy - p(j, 1), dz = cz - p(j, 2);
            const float xx = dx * dx, yy = dy * dy, zz = dz * dz;
            if ((xx + yy) + zz < r2) cand.push_back(j);
          }
        }
      }
    }
    const auto keep = std::min<std::size_t>(cand.size(), static_cast<std::size_t>(s));
    std::partial_sort(cand.begin(), cand.begin() + static_cast<std::ptrdiff_t>(keep), cand.end());
    for (std::size_t q = 0; q < keep; ++q) take(i, cand[q]);
    begin[static_cast<std::size_t>(i) + 1] = rows;
  }
  grouped.conservativeResize(rows, 3);
  return grouped;
}

namespace {

// The three nearest of `count` candidate distances d2 (lowest index first on ties).
void three_smallest(const float* d2, Eigen::Index count, Eigen::Index k, Eigen::Index* idx,
                    float* dist) {
  for (int m = 0; m < 3; ++m) {
    idx[m] = 0;
    dist[m] = INFINITY;
  }
  for (Eigen::Index j = 0; j < count; ++j) {
    if (d2[j] < dist[k - 1]) {  // insert, keeping earlier (lower-index) entries first on ties
      Eigen::Index m = k - 1;
      while (m > 0 && d2[j] < dist[m - 1]) {
        dist[m] = dist[m - 1];
        idx[m] = idx[m - 1];
        --m;
      }
      dist[m] = d2[j];
      idx[m] = j;
    }
  }
}

}  // namespace

// The 3 nearest tokens of every point: the squared distances to all tokens in one vectorised
// pass (float32 expressions identical to ops.py), then the three smallest.
DS3D_NO_FP_CONTRACT void three_nn(
    const Mat& tokens, const Mat& points, Eigen::Index k,
    Eigen::Matrix<Eigen::Index, Eigen::Dynamic, 3, Eigen::RowMajor>& idx,
    Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>& dist) {
  const Eigen::Index t = tokens.rows();
  idx.resize(points.rows(), 3);
  dist.resize(points.rows(), 3);
  const Eigen::ArrayXf tx = tokens.col(0), ty = tokens.col(1), tz = tokens.col(2);  // SoA
  const float* px = tx.data();
  const float* py = ty.data();
  const float* pz = tz.data();
  Eigen::ArrayXf d2(t);
  float* pd = d2.data();
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const float x = points(i, 0), y = points(i, 1), z = points(i, 2);
    for (Eigen::Index j = 0; j < t; ++j) {  // branch-free: vectorised (no FMA)
      const float dx = x - px[j], dy = y - py[j], dz = z - pz[j];
      const float xx = dx * dx, yy = dy * dy, zz = dz * dz;
      pd[j] = (xx + yy) + zz;
    }
    three_smallest(pd, t, k, &idx(i, 0), &dist(i, 0));
  }
}

}  // namespace ds3d::detail::htx
