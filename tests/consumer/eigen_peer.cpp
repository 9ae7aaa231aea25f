// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The peer library: allocates, reallocates and frees Eigen matrices with its own compiler flags.
#include "eigen_peer.hpp"

#include <random>

namespace eigen_peer {

Rows3f make_blobs(int n, unsigned seed) {
  std::mt19937 gen(seed);
  std::normal_distribution<float> noise(0.0F, 0.02F);
  Rows3f pts(2 * n, 3);
  for (int i = 0; i < 2 * n; ++i) {
    const float x0 = i < n ? 0.0F : 1.0F;
    pts.row(i) << x0 + noise(gen), noise(gen), 2.0F + noise(gen);
  }
  return pts;
}

Rows3f make_keypoints(int n, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<float> u01(0.0F, 1.0F);
  Rows3f kp(n, 3);
  for (int i = 0; i < n; ++i) {
    if (i % 2 == 0) {  // on the person
      kp.row(i) << 210.0F + 80.0F * u01(gen), 110.0F + 280.0F * u01(gen), 2.0F + 0.1F * u01(gen);
    } else {  // the wall behind, everywhere
      kp.row(i) << 630.0F * u01(gen), 470.0F * u01(gen), 4.0F + 0.02F * u01(gen);
    }
  }
  return kp;
}

double consume(Rows3f m) {
  m.conservativeResize(m.rows() + 7, 3);
  m.bottomRows(7).setOnes();
  return static_cast<double>(m.sum());
}

}  // namespace eigen_peer
