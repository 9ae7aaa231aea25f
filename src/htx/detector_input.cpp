// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Detector input (htx spec §6.1): gravity alignment and the seeded draw of the points.
#include "ds3d/htx/sparse_detector.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "ds3d/errors.hpp"

namespace ds3d {

void DetectorInputParams::validate() const {
  DS3D_CHECK(num_points >= 1, "ds3d::DetectorInputParams: num_points must be >= 1 (got ",
             num_points, ")");
}

Eigen::Matrix3f upright_rotation(const Eigen::Vector3d& up_cam) {
  DS3D_CHECK(up_cam.allFinite() && up_cam.norm() > 0.0,
             "ds3d::upright_rotation: up_cam must be finite and non-zero (got ", up_cam.transpose(),
             ")");
  Eigen::Matrix3d swap;  // camera (x right, y down, z fwd) -> upright (X right, Y fwd, Z up)
  swap << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  const Eigen::Vector3d n = (swap * up_cam).normalized();
  DS3D_CHECK(n.z() > 0.0, "ds3d::upright_rotation: up_cam points below the horizon (got ",
             up_cam.transpose(), ")");
  // Rows of the rotation (in the swapped frame): Z = n, Y = the optical axis (swapped: +Y)
  // projected onto the floor, X = Y x Z; the same convention as the trainer
  // (python/ds3d/htx/data.py gravity_rotation). n.z > 0 keeps the projection non-degenerate.
  const Eigen::Vector3d fwd = (Eigen::Vector3d::UnitY() - n.y() * n).normalized();
  Eigen::Matrix3d rows;
  rows.row(0) = fwd.cross(n);
  rows.row(1) = fwd;
  rows.row(2) = n;
  return (rows * swap).cast<float>();
}

DetectorInput make_detector_input(Eigen::Ref<const Points3f> cloud_cam,
                                  const Eigen::Matrix3f& R_up_cam,
                                  const DetectorInputParams& params) {
  params.validate();
  const auto n = static_cast<std::size_t>(cloud_cam.rows());
  for (std::size_t i = 0; i < n; ++i) {
    DS3D_CHECK(cloud_cam.row(static_cast<Eigen::Index>(i)).allFinite(),
               "ds3d::make_detector_input: cloud_cam row ", i, " is not finite");
  }
  DetectorInput out;
  out.R_up_cam = R_up_cam;
  if (n == 0) return out;
  // SplitMix64 (Steele et al. 2014): tiny, and the same stream on every platform, which
  // std::uniform_int_distribution does not promise.
  std::uint64_t state = params.seed;
  const auto next = [&state](std::uint64_t bound) {
    state += 0x9E3779B97F4A7C15ULL;
    std::uint64_t z = state;
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return (z ^ (z >> 31U)) % bound;  // bias < bound / 2^64
  };
  const auto m = static_cast<std::size_t>(params.num_points);
  std::vector<std::uint32_t> rows(std::max(n, m));
  std::iota(rows.begin(), rows.begin() + static_cast<std::ptrdiff_t>(n), 0U);
  for (std::size_t i = n; i < m; ++i) rows[i] = static_cast<std::uint32_t>(next(n));
  // Partial Fisher-Yates: the first m entries become a uniform random draw in random order.
  for (std::size_t i = 0; i < m; ++i) {
    const std::size_t j = i + static_cast<std::size_t>(next(rows.size() - i));
    std::swap(rows[i], rows[j]);
  }
  rows.resize(m);
  out.points.resize(static_cast<Eigen::Index>(m), 3);
  for (std::size_t i = 0; i < m; ++i) {
    out.points.row(static_cast<Eigen::Index>(i)) =
        (R_up_cam * cloud_cam.row(static_cast<Eigen::Index>(rows[i])).transpose()).transpose();
  }
  out.rows = std::move(rows);
  return out;
}

}  // namespace ds3d
