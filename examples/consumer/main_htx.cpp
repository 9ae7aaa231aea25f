// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The HTx-lite detector from an installed package through ds3d::htx alone (Eigen; no OpenCV, no
// Ceres): load the shipped weights, detect people in one gravity-aligned view of a room.
// Usage: app_htx WEIGHTS   (e.g. <prefix>/share/ds3d/models/htx_lite_fast.safetensors)
#include <cmath>
#include <cstdio>
#include <random>

#include <ds3d/htx/sparse_detector.hpp>

namespace {

// One view of a room in the detector's frame (X right, Y forward, Z up; floor removed as the
// preprocessing does): a back wall, a table, and a standing person 2 m in front of the camera,
// each sampled on the surfaces the camera sees.
ds3d::Points3f room_with_person(int n) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  ds3d::Points3f pts(n, 3);
  for (int i = 0; i < n; ++i) {
    const float a = u(gen), b = u(gen);
    if (i % 4 < 2) {  // back wall, 4 m away
      pts.row(i) << -2.0F + 4.0F * a, 4.0F, 0.02F + 2.5F * b;
    } else if (i % 4 == 2) {  // a table top and its front
      pts.row(i) << -1.6F + 0.9F * a, 2.6F + 0.5F * b, 0.75F;
    } else {  // a person: the camera-facing half of an elliptic cylinder, 1.75 m tall
      const float phi = 3.14159265F * (1.0F + a);
      pts.row(i) << 0.4F + 0.22F * std::cos(phi), 2.0F + 0.14F * std::sin(phi), 0.02F + 1.73F * b;
    }
  }
  return pts;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s WEIGHTS\n", argv[0]);
    return 2;
  }
  const auto det = ds3d::SparseDetector::load(argv[1]);
  const auto boxes = det.detect(room_with_person(4096));
  std::printf("ds3d::htx '%s': %zu boxes\n", det.config().profile.c_str(), boxes.size());
  int people = 0;
  for (const auto& b : boxes) {
    const bool ok = b.centre.allFinite() && b.size.allFinite() && std::isfinite(b.score);
    if (!ok) return 1;
    std::printf("  %s score %.2f at (%.2f, %.2f, %.2f) m, size %.2f x %.2f x %.2f m\n",
                det.config().class_names.at(static_cast<std::size_t>(b.label)).c_str(),
                static_cast<double>(b.score), static_cast<double>(b.centre.x()),
                static_cast<double>(b.centre.y()), static_cast<double>(b.centre.z()),
                static_cast<double>(b.size.x()), static_cast<double>(b.size.y()),
                static_cast<double>(b.size.z()));
    people += (b.centre.head<2>() - Eigen::Vector2f(0.4F, 2.0F)).norm() < 0.5F ? 1 : 0;
  }
  std::printf("person found: %s\n", people > 0 ? "yes" : "no");
  return 0;
}
