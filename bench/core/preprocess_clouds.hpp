// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Benchmark clouds for the preprocessing components: the rendered room (tests/support/
// depth_scene.hpp) back-projected at 640x480 (~300k points) and 1280x800 (~1M points).
#include "ds3d/preprocess/rgbd.hpp"
#include "support/depth_scene.hpp"

namespace ds3d::bench {

/// Camera for a frame of about `points` valid pixels (300k: 640x480; 1M: 1280x800).
inline PinholeCamera bench_camera(std::int64_t points) {
  PinholeCamera cam;
  if (points > 400'000) {
    cam.width = 1280;
    cam.height = 800;
    cam.fx = cam.fy = 1050.0;
    cam.cx = 639.5;
    cam.cy = 399.5;
  }
  return cam;
}

/// Rendered room frame back-projected to points; cached per size.
inline const Points3f& room_cloud(std::int64_t points) {
  static Points3f small;
  static Points3f large;
  Points3f& p = points > 400'000 ? large : small;
  if (p.rows() == 0) {
    const auto frame = test::render_room(1, bench_camera(points));
    p = depth_to_points(frame.depth.data(), frame.camera.width, frame.camera.height,
                        frame.camera.width, frame.camera)
            .points;
  }
  return p;
}

}  // namespace ds3d::bench
