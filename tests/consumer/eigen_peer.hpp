// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// A stand-in for an Eigen-using library of a SLAM system (g2o, Sophus): built with its own flags.
#pragma once

#include <Eigen/Core>

namespace eigen_peer {

using Rows3f = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Two Gaussian blobs of `n` points each (1 m apart, sigma 2 cm); allocated in this library.
Rows3f make_blobs(int n, unsigned seed);
/// `n` keypoints (u, v, depth): half on a person at 2 m inside the pixel box (200..300,
/// 100..400), half on a wall at 4 m all over the image; allocated in this library.
Rows3f make_keypoints(int n, unsigned seed);
/// Takes ownership of `m` (allocated by the caller), grows it (reallocated and freed here) and
/// returns the sum of its finite entries.
double consume(Rows3f m);

}  // namespace eigen_peer
