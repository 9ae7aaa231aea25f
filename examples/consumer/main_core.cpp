// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Header-only use of ds3d::core from an installed package: read a user point type via traits.
#include <cstdio>
#include <vector>

#include <ds3d/ds3d.hpp>

struct P {
  float x, y, z;
};
template <>
struct ds3d::PointCloudTraits<std::vector<P>> {
  static std::size_t size(const std::vector<P>& c) { return c.size(); }
  static Eigen::Vector3f point(const std::vector<P>& c, std::size_t i) {
    return {c[i].x, c[i].y, c[i].z};
  }
};

int main() {
  const std::vector<P> cloud{{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  const ds3d::Points3f pts = ds3d::cloud::to_points3f(cloud);
  std::printf("ds3d %s core: %zu points, sum z = %.1f\n", ds3d::kVersion,
              static_cast<std::size_t>(pts.rows()), static_cast<double>(pts.col(2).sum()));
  return pts.rows() == 3 ? 0 : 1;
}
