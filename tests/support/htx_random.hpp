// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Random HTx weights built in C++ (for tests and benchmarks that must not depend on Python).
// The values are plausible in scale only; parity with PyTorch is tested by python/tests.

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "ds3d/htx/sparse_detector.hpp"
#include "ds3d/htx/weights_io.hpp"
#include "support/synthetic.hpp"

namespace ds3d::test {

/// Tensors of a random detector for `config`: weights ~ U(+-1/sqrt(fan_in)), LayerNorm gains 1.
inline std::vector<NamedTensor> random_htx_tensors(const DetectorConfig& config,
                                                   std::uint64_t seed) {
  Rng rng(seed);
  std::vector<NamedTensor> out;
  for (const auto& [name, shape] : SparseDetector::expected_tensors(config)) {
    NamedTensor t{name, shape, {}};
    std::int64_t n = 1;
    for (const auto s : shape) n *= s;
    const bool is_norm = name.find("norm") != std::string::npos;
    const double bound = shape.size() == 2 ? 1.0 / std::sqrt(static_cast<double>(shape[1])) : 0.1;
    for (std::int64_t i = 0; i < n; ++i) {
      double v = name == "pos_embedding.gauss_B" ? rng.normal() : rng.uniform(-bound, bound);
      if (is_norm && name.ends_with(".weight")) v = 1.0 + 0.1 * v;
      t.data.push_back(static_cast<float>(v));
    }
    out.push_back(std::move(t));
  }
  return out;
}

/// The bytes of a complete random weights file.
inline std::string random_htx_file(const DetectorConfig& config, std::uint64_t seed) {
  return serialize_safetensors(
      random_htx_tensors(config, seed),
      {{"format", "ds3d-htx"}, {"version", "1"}, {"config", config.to_json()}});
}

/// A person-sized column, a table and two walls: n points, gravity-aligned (Z up).
inline Points3f htx_scene(std::size_t n, std::uint64_t seed) {
  Rng rng(seed);
  Points3f p(static_cast<Eigen::Index>(n), 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const int part = static_cast<int>(i % 4);
    const double lo[4][3] = {{-2.0, 3.9, 0.0}, {-2.0, 0.5, 0.0}, {0.2, 1.5, 0.0}, {-1.0, 2.5, 0.0}};
    const double hi[4][3] = {{2.0, 4.0, 2.5}, {-1.9, 4.0, 2.5}, {0.7, 2.0, 1.7}, {0.0, 3.2, 0.8}};
    for (int a = 0; a < 3; ++a) p(i, a) = static_cast<float>(rng.uniform(lo[part][a], hi[part][a]));
  }
  return p;
}

}  // namespace ds3d::test
