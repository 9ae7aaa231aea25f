// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// An analytic RGB-D room rendered by ray casting (tests, benchmarks and the demo): camera at the
// origin looking along +z, y down, floor 1.2 m below, back wall, side walls, ceiling, a table-like
// box and a person-sized box. Kinect-like noise (sigma 1.5 mm · z^2), 16-bit TUM depth units,
// random dropouts and a few speckle outliers. Deterministic for a given seed.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "ds3d/camera.hpp"
#include "support/synthetic.hpp"

namespace ds3d::test {

/// A rendered frame: row-major width×height depth in camera.depth_scale units (0 = invalid).
struct DepthFrame {
  PinholeCamera camera;
  std::vector<std::uint16_t> depth;
};

namespace scene_detail {
/// Ray (origin 0, direction d with d.z = 1) against an axis-aligned box; returns t or +inf.
inline double ray_box(const double d[3], const double lo[3], const double hi[3]) {
  double t0 = 0.0;
  double t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (0.0 < lo[a] || 0.0 > hi[a]) return std::numeric_limits<double>::infinity();
      continue;
    }
    double ta = lo[a] / d[a];
    double tb = hi[a] / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1 && t0 > 0.0 ? t0 : std::numeric_limits<double>::infinity();
}
}  // namespace scene_detail

/// Renders the room at `camera` resolution (default 640×480, fx = fy = 525).
/// `person_x` moves the person box along x [m]; dropout is the fraction of invalid pixels.
inline DepthFrame render_room(std::uint64_t seed, const PinholeCamera& camera = {},
                              double person_x = 0.6, double dropout = 0.02) {
  Rng rng(seed);
  DepthFrame f;
  f.camera = camera;
  const int w = camera.width;
  const int h = camera.height;
  f.depth.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0);
  const double table_lo[3] = {-0.9, 0.45, 2.2};
  const double table_hi[3] = {0.1, 1.2, 3.0};
  const double person_lo[3] = {person_x - 0.25, -0.5, 2.6};
  const double person_hi[3] = {person_x + 0.25, 1.2, 2.9};
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const double d[3] = {(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0};
      double t = std::numeric_limits<double>::infinity();
      if (d[1] > 0) t = std::min(t, 1.2 / d[1]);   // floor y = 1.2
      if (d[1] < 0) t = std::min(t, -1.4 / d[1]);  // ceiling y = -1.4
      if (d[0] < 0) t = std::min(t, -2.0 / d[0]);  // left wall x = -2
      if (d[0] > 0) t = std::min(t, 2.3 / d[0]);   // right wall x = 2.3
      t = std::min(t, 4.6);                        // back wall z = 4.6
      t = std::min(t, scene_detail::ray_box(d, table_lo, table_hi));
      t = std::min(t, scene_detail::ray_box(d, person_lo, person_hi));
      double z = t;  // d.z = 1, so the ray parameter is the depth
      z += 0.0015 * z * z * rng.normal();
      if (rng.uniform() < 0.002) z = rng.uniform(0.5, 4.5);  // speckle
      if (rng.uniform() < dropout) z = 0.0;
      const double units = std::round(z * camera.depth_scale);
      f.depth[static_cast<std::size_t>(v) * static_cast<std::size_t>(w) +
              static_cast<std::size_t>(u)] =
          static_cast<std::uint16_t>(std::clamp(units, 0.0, 65535.0));
    }
  }
  return f;
}

}  // namespace ds3d::test
