// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Demo step 20: a synthetic 640x480 depth frame of a room (rendered analytically below), turned
// into the detector input by ds3d::preprocess; prints the counts and timings of every stage.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <iostream>
#include <limits>
#include <vector>

#include "ds3d/preprocess/preprocess.hpp"
#include "ds3d_demo/demo.hpp"

namespace {

/// Depth [m] along the ray through pixel (u, v) into a 4.3 x 2.6 x 4.6 m room (camera 1.2 m
/// above the floor, y down) with a table and a person-sized box; 0 if nothing is hit.
double room_depth(const ds3d::PinholeCamera& cam, int u, int v) {
  const double d[3] = {(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0};
  double t = 4.6;                              // back wall z = 4.6 (d.z = 1: t is the depth)
  if (d[1] > 0) t = std::min(t, 1.2 / d[1]);   // floor
  if (d[1] < 0) t = std::min(t, -1.4 / d[1]);  // ceiling
  if (d[0] < 0) t = std::min(t, -2.0 / d[0]);  // left wall
  if (d[0] > 0) t = std::min(t, 2.3 / d[0]);   // right wall
  const double boxes[2][6] = {{-0.9, 0.45, 2.2, 0.1, 1.2, 3.0}, {0.35, -0.5, 2.6, 0.85, 1.2, 2.9}};
  for (const auto& b : boxes) {
    double t0 = 0.0;
    double t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      double ta = b[a] / d[a];
      double tb = b[a + 3] / d[a];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
    }
    if (t0 <= t1 && t0 > 0.0) t = std::min(t, t0);
  }
  return t;
}

}  // namespace

DS3D_DEMO_STEP(
    20, "preprocessing: depth frame -> detector input", [](const ds3d::demo::Context& ctx) {
      const ds3d::PinholeCamera cam;  // 640x480, fx = fy = 525, TUM depth scale 5000
      std::vector<std::uint16_t> depth(static_cast<std::size_t>(cam.width * cam.height));
      std::uint64_t state = ctx.seed;  // tiny LCG: sensor-like noise and 2 % dropouts
      auto next = [&state] {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        return static_cast<double>(state >> 11U) * (1.0 / 9007199254740992.0);
      };
      for (int v = 0; v < cam.height; ++v) {
        for (int u = 0; u < cam.width; ++u) {
          double z = room_depth(cam, u, v);
          z += 0.0015 * z * z * (next() + next() + next() - 1.5) * 2.0;  // ~ sigma 1.5 mm z^2
          if (next() < 0.02) z = 0.0;
          depth[static_cast<std::size_t>(v * cam.width + u)] =
              static_cast<std::uint16_t>(std::clamp(std::round(z * cam.depth_scale), 0.0, 65535.0));
        }
      }
      ds3d::PreprocessParams params;
      // Defaults: stride 2, leaf 0.1 m (~4k detector points), ground prior -y, R 0.25 m, k 4.
      const int runs = ctx.quick ? 3 : 21;
      std::vector<double> ms;
      ds3d::PreprocessResult r;
      for (int i = 0; i < runs; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        r = ds3d::preprocess(depth.data(), cam.width, cam.height, cam.width, cam, params);
        ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
      }
      std::sort(ms.begin(), ms.end());
      std::cout << std::fixed << std::setprecision(2);
      std::cout << "640x480 depth: " << r.num_input << " points -> " << r.num_voxels
                << " voxel centroids (stride 2, leaf 0.1 m) -> " << r.num_ground << " ground ("
                << (r.ground_found ? "plane found" : "no plane")
                << ": n = " << r.ground_plane.head<3>().transpose() << ", d = " << r.ground_plane[3]
                << ") -> " << r.num_outliers << " outliers -> " << r.points.rows()
                << " detector points\n";
      std::cout << "stage times of the last run [ms]: depth " << r.ms_depth << ", voxel "
                << r.ms_voxel << ", ground " << r.ms_ground << ", outliers " << r.ms_outlier
                << "; median of " << runs << " runs: " << ms[ms.size() / 2] << " ms (one thread)\n";
    });
