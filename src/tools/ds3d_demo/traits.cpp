// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Demo step 10: a user point type read through ds3d's traits, with a non-finite point counted.
#include <cstdint>
#include <iostream>
#include <limits>
#include <vector>

#include "ds3d/cloud.hpp"
#include "ds3d_demo/demo.hpp"

namespace {
struct ColoredPoint {
  float x, y, z;
  std::uint8_t r, g, b;
};
}  // namespace

template <>
struct ds3d::PointCloudTraits<std::vector<ColoredPoint>> {
  static std::size_t size(const std::vector<ColoredPoint>& c) { return c.size(); }
  static Eigen::Vector3f point(const std::vector<ColoredPoint>& c, std::size_t i) {
    return {c[i].x, c[i].y, c[i].z};
  }
};

DS3D_DEMO_STEP(10, "point traits: your own point type", [](const ds3d::demo::Context&) {
  std::vector<ColoredPoint> cloud;
  for (int i = 0; i < 1000; ++i) {
    const float t = static_cast<float>(i) * 0.01F;
    cloud.push_back({t, 2.0F * t, 1.5F, 255, 0, 0});
  }
  cloud[17].y = std::numeric_limits<float>::quiet_NaN();
  std::size_t non_finite = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < ds3d::cloud::size(cloud); ++i) {
    const Eigen::Vector3f p = ds3d::cloud::point(cloud, i);
    if (!ds3d::cloud::is_finite(p)) {
      ++non_finite;
      continue;
    }
    sum += p.cast<double>();
  }
  const auto n = static_cast<double>(ds3d::cloud::size(cloud) - non_finite);
  std::cout << "read " << ds3d::cloud::size(cloud) << " user points through PointCloudTraits, "
            << non_finite << " non-finite skipped; centroid = " << (sum / n).transpose() << "\n";
});
