// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// libFuzzer target: HDBSCAN on fuzzer-chosen points and parameters. Bytes 0-3 pick the
// parameters and the dimension (1-4), the rest are raw little-endian doubles (at most 192
// points). Only ds3d::InvalidArgument may escape (non-finite coordinates, bad scale); labels
// must lie in [-1, num_clusters) and probabilities in [0, 1]. Run with `make fuzz`.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/errors.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 4) return 0;
  ds3d::HdbscanParams p;
  p.min_cluster_size = 2 + data[0] % 16;
  p.min_samples = data[1] % 16;
  p.cluster_selection_method =
      (data[2] & 1) != 0 ? ds3d::ClusterSelection::kLeaf : ds3d::ClusterSelection::kEom;
  p.allow_single_cluster = (data[2] & 2) != 0;
  p.algorithm = static_cast<ds3d::MstAlgorithm>((data[2] >> 2) % 3);
  p.cluster_selection_epsilon = (data[2] & 16) != 0 ? 0.5 : 0.0;
  p.max_cluster_size = (data[2] & 32) != 0 ? 8 : 0;
  const int dims = 1 + data[3] % 4;
  const std::size_t n =
      std::min<std::size_t>((size - 4) / (8 * static_cast<std::size_t>(dims)), 192);
  ds3d::RowMatrixXd pts(static_cast<Eigen::Index>(n), dims);
  for (std::size_t i = 0; i < n * static_cast<std::size_t>(dims); ++i) {
    double v = 0;
    std::memcpy(&v, data + 4 + 8 * i, 8);
    pts.data()[i] = v;
  }
  ds3d::HdbscanResult r;
  try {
    r = ds3d::hdbscan(pts, p);
  } catch (const ds3d::InvalidArgument&) {
    return 0;  // non-finite coordinates
  }
  if (r.labels.size() != n || r.probabilities.size() != n) std::abort();
  for (std::size_t i = 0; i < n; ++i) {
    if (r.labels[i] < -1 || r.labels[i] >= r.num_clusters) std::abort();
    if (!(r.probabilities[i] >= 0.0 && r.probabilities[i] <= 1.0)) std::abort();
  }
  return 0;
}
