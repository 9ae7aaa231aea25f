// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Calls the compiled ds3d::htx: links only when this file shares the library's Eigen ABI.
#include <cmath>
#include <cstdio>

#include <ds3d/htx/sparse_detector.hpp>

int main() {
  const Eigen::Matrix3f R = ds3d::upright_rotation(Eigen::Vector3d(0.0, -1.0, 0.0));
  const bool ok = R.allFinite() && (R.transpose() * R - Eigen::Matrix3f::Identity()).norm() < 1e-4F;
  std::printf("htx_guard: upright rotation %s\n", ok ? "OK" : "FAILED");
  return ok ? 0 : 1;
}
