// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Demo step 30: HDBSCAN on synthetic ORB-like keypoints of a person in front of a background,
// clustered in (u px, v px, depth m × 100) so 1 cm of depth weighs like 1 px.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <iostream>
#include <random>
#include <vector>

#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d_demo/demo.hpp"

namespace {

struct Keypoints {
  ds3d::RowMatrixXd uvd;       // (u, v, depth m)
  std::vector<int> on_person;  // ground truth: 1 person, 0 background, -1 outlier
};

Keypoints make_keypoints(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  auto uni = [&](double lo, double hi) {
    return lo + (hi - lo) * (static_cast<double>(rng() >> 11U) * 0x1.0p-53);
  };
  auto normal = [&]() {
    const double u1 = 1.0 - uni(0.0, 1.0);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * uni(0.0, 1.0));
  };
  Keypoints k;
  k.uvd.resize(static_cast<Eigen::Index>(n), 3);
  k.on_person.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    const double kind = uni(0.0, 1.0);
    if (kind < 0.55) {  // person: torso/head box, 1.6 m, some body relief
      k.uvd(r, 0) = uni(260, 380) + 6.0 * normal();
      k.uvd(r, 1) = uni(100, 440);
      k.uvd(r, 2) = 1.6 + 0.05 * normal();
      k.on_person[i] = 1;
    } else if (kind < 0.95) {  // background: tilted plane at 3-5 m
      k.uvd(r, 0) = uni(0, 640);
      k.uvd(r, 1) = uni(0, 480);
      k.uvd(r, 2) = 3.0 + 2.0 * k.uvd(r, 1) / 480.0 + 0.01 * normal();
      k.on_person[i] = 0;
    } else {  // flying pixels / gross depth outliers
      k.uvd(r, 0) = uni(0, 640);
      k.uvd(r, 1) = uni(0, 480);
      k.uvd(r, 2) = uni(0.5, 6.0);
      k.on_person[i] = -1;
    }
  }
  return k;
}

void run_hdbscan_step(const ds3d::demo::Context& c) {
  const std::size_t n = c.quick ? 500 : 2000;
  const Keypoints k = make_keypoints(n, c.seed);
  ds3d::HdbscanParams p;
  p.min_cluster_size = 15;
  p.min_samples = 10;
  const std::vector<double> scale{1.0, 1.0, 100.0};  // metres -> "centimetre pixels"
  const auto t0 = std::chrono::steady_clock::now();
  const ds3d::HdbscanResult r = ds3d::hdbscan(k.uvd, p, scale);
  const auto t1 = std::chrono::steady_clock::now();
  const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  std::cout << "clustered " << n << " keypoints in " << std::fixed << std::setprecision(2) << ms
            << " ms (" << ds3d::to_string(p.algorithm) << " MST): " << r.num_clusters
            << " clusters, " << std::count(r.labels.begin(), r.labels.end(), -1) << " noise\n";
  for (int l = 0; l < r.num_clusters; ++l) {
    std::size_t size = 0, person = 0;
    double depth = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (r.labels[i] != l) continue;
      ++size;
      person += k.on_person[i] == 1 ? 1U : 0U;
      depth += k.uvd(static_cast<Eigen::Index>(i), 2);
    }
    std::cout << "  cluster " << l << ": " << size << " keypoints, mean depth "
              << std::setprecision(2) << depth / static_cast<double>(size) << " m, "
              << (100 * person / size) << "% on the person\n";
  }
}

}  // namespace

DS3D_DEMO_STEP(30, "HDBSCAN: cluster keypoints in (u, v, depth)", run_hdbscan_step);
