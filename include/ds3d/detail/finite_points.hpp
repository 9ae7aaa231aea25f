// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// The finite points of any PointCloud as structure-of-arrays floats with their input indices
// (for vectorised loops). Not API.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "ds3d/cloud.hpp"
#include "ds3d/errors.hpp"

namespace ds3d::detail {

/// Finite points of a cloud in structure-of-arrays form, with their input indices.
struct FinitePoints {
  std::vector<float> x, y, z;
  std::vector<std::uint32_t> index;  ///< input row of each stored point, ascending
  std::size_t num_non_finite = 0;
  [[nodiscard]] std::size_t size() const { return index.size(); }
};

/// Copies the finite points of `c` (SoA) and counts the others; throws InvalidArgument naming
/// `function` when `on_non_finite` is kThrow and one is found, or for >= 2^32 - 1 points.
template <PointCloud C>
[[nodiscard]] FinitePoints gather_finite(const C& c, NonFinite on_non_finite,
                                         const char* function) {
  const std::size_t n = cloud::size(c);
  DS3D_CHECK(n < std::numeric_limits<std::uint32_t>::max(), function,
             ": clouds are limited to 2^32 - 1 points (got ", n, ")");
  FinitePoints f;
  f.x.reserve(n);
  f.y.reserve(n);
  f.z.reserve(n);
  f.index.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f p = cloud::point(c, i);
    if (!cloud::is_finite(p)) {
      DS3D_CHECK(on_non_finite != NonFinite::kThrow, function, ": point ", i, " is not finite (",
                 p.x(), ", ", p.y(), ", ", p.z(), ")");
      ++f.num_non_finite;
      continue;
    }
    f.x.push_back(p.x());
    f.y.push_back(p.y());
    f.z.push_back(p.z());
    f.index.push_back(static_cast<std::uint32_t>(i));
  }
  return f;
}

}  // namespace ds3d::detail
