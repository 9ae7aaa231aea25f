// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Synthetic ORB-like keypoints of a person in front of a tilted background plane in a 640×480
// RGB-D frame, as (u px, v px, depth m × depth_scale) rows: the per-frame HDBSCAN workload.
// Keypoints clump at texture hot spots; a few percent are flying pixels (depth between person and
// background) and gross depth outliers. Deterministic for a given seed.

#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "support/synthetic.hpp"

namespace ds3d::test {

inline Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> person_keypoints(
    std::size_t n, std::uint64_t seed, double depth_scale = 100.0) {
  Rng rng(seed);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> x(
      static_cast<Eigen::Index>(n), 3);
  const double person_z = 1.6;
  // Hot spots: 12 on the person (inside a 180×380 px box), 10 on the background.
  std::vector<Eigen::Vector2d> hot;
  for (int k = 0; k < 22; ++k) {
    hot.emplace_back(k < 12 ? Eigen::Vector2d(rng.uniform(240, 400), rng.uniform(90, 450))
                            : Eigen::Vector2d(rng.uniform(0, 640), rng.uniform(0, 480)));
  }
  for (std::size_t i = 0; i < n; ++i) {
    const double kind = rng.uniform();
    const auto k = static_cast<std::size_t>(rng.next() % hot.size());
    const double u = std::clamp(hot[k].x() + 18.0 * rng.normal(), 0.0, 639.0);
    const double v = std::clamp(hot[k].y() + 18.0 * rng.normal(), 0.0, 479.0);
    double z =
        k < 12 ? person_z + 0.15 * std::sin(0.02 * u) * std::cos(0.015 * v) : 3.0 + 2.0 * v / 480.0;
    z += 2.0 * (0.0012 + 0.0019 * (z - 0.4) * (z - 0.4)) * rng.normal();  // Kinect noise ×2
    if (kind < 0.03)
      z = rng.uniform(person_z, 3.0);  // flying pixels
    else if (kind < 0.05)
      z = rng.uniform(0.5, 6.0);  // gross outliers
    const auto r = static_cast<Eigen::Index>(i);
    x(r, 0) = u;
    x(r, 1) = v;
    x(r, 2) = z * depth_scale;
  }
  return x;
}

}  // namespace ds3d::test
