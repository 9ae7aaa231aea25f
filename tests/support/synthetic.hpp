// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Seeded synthetic scenes shared by tests and benchmarks (STYLE.md §9): planes, boxes, blobs,
// uniform noise and one moving object. Deterministic for a given seed on every platform (uses
// std::mt19937_64 and our own uniform/normal transforms, not std::*_distribution, whose output
// is implementation-defined).

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "ds3d/cloud.hpp"

namespace ds3d::test {

/// Portable RNG: uniform doubles in [0,1) and standard normals (Box-Muller).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  double uniform() { return static_cast<double>(gen_() >> 11U) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }
  std::uint64_t next() { return gen_(); }

 private:
  std::mt19937_64 gen_;
};

/// n points on the plane z = 0 within [-half, half]^2, with Gaussian noise sigma along z.
inline Points3f plane_points(std::size_t n, double half, double sigma, Rng& rng) {
  Points3f p(static_cast<Eigen::Index>(n), 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    p(i, 0) = static_cast<float>(rng.uniform(-half, half));
    p(i, 1) = static_cast<float>(rng.uniform(-half, half));
    p(i, 2) = static_cast<float>(sigma * rng.normal());
  }
  return p;
}

/// n points uniform in the axis-aligned box [lo, hi].
inline Points3f uniform_box(std::size_t n, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                            Rng& rng) {
  Points3f p(static_cast<Eigen::Index>(n), 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    for (int d = 0; d < 3; ++d) p(i, d) = static_cast<float>(rng.uniform(lo[d], hi[d]));
  }
  return p;
}

/// n points on the surface of a box with the given centre and full sizes.
inline Points3f box_surface(std::size_t n, const Eigen::Vector3d& centre,
                            const Eigen::Vector3d& size, Rng& rng) {
  Points3f p(static_cast<Eigen::Index>(n), 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    Eigen::Vector3d q(rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5));
    const int face = static_cast<int>(rng.next() % 3U);
    q[face] = rng.uniform() < 0.5 ? -0.5 : 0.5;
    p.row(i) = (centre + q.cwiseProduct(size)).cast<float>().transpose();
  }
  return p;
}

/// Isotropic Gaussian blobs in `dim` dimensions plus a fraction of uniform noise over the
/// blobs' bounding box; returns an n×dim row-major double matrix and the true blob id (-1 noise).
struct Blobs {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> x;
  std::vector<int> label;
};
inline Blobs gaussian_blobs(std::size_t n, int dim, int centres, double noise_fraction,
                            std::uint64_t seed, double spread = 10.0, double sigma = 0.5) {
  Rng rng(seed);
  Blobs b;
  b.x.resize(static_cast<Eigen::Index>(n), dim);
  b.label.resize(n);
  std::vector<Eigen::VectorXd> c(static_cast<std::size_t>(centres), Eigen::VectorXd(dim));
  for (auto& v : c) {
    for (int d = 0; d < dim; ++d) v[d] = rng.uniform(-spread, spread);
  }
  const auto n_noise = static_cast<std::size_t>(std::llround(noise_fraction * double(n)));
  for (std::size_t i = 0; i < n; ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    if (i < n - n_noise) {
      const auto k = i % c.size();
      for (int d = 0; d < dim; ++d) b.x(r, d) = c[k][d] + sigma * rng.normal();
      b.label[i] = static_cast<int>(k);
    } else {
      for (int d = 0; d < dim; ++d) b.x(r, d) = rng.uniform(-1.2 * spread, 1.2 * spread);
      b.label[i] = -1;
    }
  }
  return b;
}

/// A small static room (floor z = 0, two walls, a table-like box) with one object moving along
/// +x by `t * speed` metres: `moving` marks the object's points.
struct MovingScene {
  Points3f points;
  std::vector<bool> moving;
};
inline MovingScene moving_object_scene(std::size_t n_static, std::size_t n_object, double t,
                                       std::uint64_t seed, double speed = 0.5) {
  Rng rng(seed);
  const Points3f floor = plane_points(n_static / 2, 2.5, 0.002, rng);
  const Points3f wall = box_surface(n_static - n_static / 2, {0, 0, 1.25}, {5, 5, 2.5}, rng);
  const Points3f obj = box_surface(n_object, {-1.0 + speed * t, 0.5, 0.9}, {0.4, 0.3, 1.7}, rng);
  MovingScene s;
  s.points.resize(floor.rows() + wall.rows() + obj.rows(), 3);
  s.points << floor, wall, obj;
  s.moving.assign(static_cast<std::size_t>(s.points.rows()), false);
  for (Eigen::Index i = floor.rows() + wall.rows(); i < s.points.rows(); ++i) {
    s.moving[static_cast<std::size_t>(i)] = true;
  }
  return s;
}

}  // namespace ds3d::test
