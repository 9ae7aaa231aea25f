// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// smooth_poses: Gauss-Newton over all free poses of a sequence, banded sparse normal equations.
#include "ds3d/slam/pose_smoothing.hpp"

#include <cmath>
#include <cstddef>
#include <vector>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "ds3d/errors.hpp"

namespace ds3d::slam {

void PoseSmoothingParams::validate() const {
  constexpr const char* f = "ds3d::slam::PoseSmoothingParams";
  DS3D_CHECK(std::isfinite(acceleration_sigma) && acceleration_sigma > 0, f,
             ": acceleration_sigma must be > 0 (got ", acceleration_sigma, ")");
  DS3D_CHECK(std::isfinite(max_gap) && max_gap > 0, f, ": max_gap must be > 0 (got ", max_gap, ")");
  DS3D_CHECK(iterations >= 1, f, ": iterations must be >= 1 (got ", iterations, ")");
  DS3D_CHECK(std::isfinite(chi2_mono) && chi2_mono > 0, f, ": chi2_mono must be > 0 (got ",
             chi2_mono, ")");
  DS3D_CHECK(std::isfinite(chi2_stereo) && chi2_stereo > 0, f, ": chi2_stereo must be > 0 (got ",
             chi2_stereo, ")");
}

namespace {

using Mat36 = Eigen::Matrix<double, 3, 6>;

// Three consecutive linked frames and the weights of the camera centres' second divided
// difference, a = Σ alpha_j C_j [m/s²].
struct Triple {
  std::size_t idx[3];
  double alpha[3];
};

void check_frames(const std::vector<SmoothingFrame>& frames) {
  constexpr const char* f = "ds3d::slam::smooth_poses";
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const SmoothingFrame& s = frames[i];
    DS3D_CHECK(std::isfinite(s.timestamp), f, ": frames[", i, "].timestamp must be finite (got ",
               s.timestamp, ")");
    DS3D_CHECK(i == 0 || s.timestamp > frames[i - 1].timestamp, f, ": frames[", i,
               "].timestamp must increase (got ", s.timestamp, " after ", frames[i - 1].timestamp,
               ")");
    DS3D_CHECK(s.T_cam_world.matrix().allFinite(), f, ": frames[", i,
               "].T_cam_world must be finite");
    DS3D_CHECK(s.points.size() == s.observations.size(), f, ": frames[", i, "] has ",
               s.points.size(), " points but ", s.observations.size(), " observations");
  }
}

// Triples of valid frames with both gaps in (0, max_gap] and at least one free member.
std::vector<Triple> link_triples(const std::vector<SmoothingFrame>& frames, double max_gap) {
  std::vector<Triple> out;
  for (std::size_t b = 1; b + 1 < frames.size(); ++b) {
    const SmoothingFrame& A = frames[b - 1];
    const SmoothingFrame& B = frames[b];
    const SmoothingFrame& C = frames[b + 1];
    if (!A.valid || !B.valid || !C.valid) continue;
    if (A.fixed && B.fixed && C.fixed) continue;
    const double d1 = B.timestamp - A.timestamp;
    const double d2 = C.timestamp - B.timestamp;
    if (d1 > max_gap || d2 > max_gap) continue;
    const double a = 2.0 / (d1 * (d1 + d2));
    const double c = 2.0 / (d2 * (d1 + d2));
    out.push_back({{b - 1, b, b + 1}, {a, -(a + c), c}});
  }
  return out;
}

Eigen::Vector3d centre(const Eigen::Isometry3d& T_cw) {
  return -(T_cw.linear().transpose() * T_cw.translation());
}

struct System {
  std::vector<Eigen::Triplet<double>> h;
  Eigen::VectorXd b;
  double cost = 0;
};

// Huber-weighted observation terms of one free frame (block `col` of the unknowns).
void add_observations(const StereoIntrinsics& k, const SmoothingFrame& f,
                      const Eigen::Isometry3d& T, const PoseSmoothingParams& params, int col,
                      System& s, bool linearise) {
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
  for (std::size_t i = 0; i < f.points.size(); ++i) {
    double res[3];
    double jp[18];
    const int d = reprojection_residual(k, T, f.points[i], f.observations[i], res,
                                        linearise ? jp : nullptr, nullptr);
    if (d == 0) continue;
    const Eigen::Map<const Eigen::VectorXd> e(res, d);
    const double chi2 = e.squaredNorm();
    const double th = d == 3 ? params.chi2_stereo : params.chi2_mono;
    // Huber: ρ(χ²) = χ² inside, 2δ√χ² − δ² outside; IRLS weight min(1, δ/√χ²).
    s.cost += chi2 <= th ? chi2 : 2.0 * std::sqrt(th * chi2) - th;
    if (!linearise) continue;
    const double w = chi2 <= th ? 1.0 : std::sqrt(th / chi2);
    const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>> J(jp, d, 6);
    H += w * J.transpose() * J;
    g += w * J.transpose() * e;
  }
  if (!linearise) return;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) s.h.emplace_back(col * 6 + r, col * 6 + c, H(r, c));
  }
  s.b.segment<6>(col * 6) += g;
}

// The acceleration term of one triple; `col[j]` < 0 for a fixed member.
void add_triple(const Triple& t, const std::vector<Eigen::Isometry3d>& T, const int* col,
                double inv_sigma, System& s, bool linearise) {
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  for (int j = 0; j < 3; ++j) r += t.alpha[j] * centre(T[t.idx[j]]);
  r *= inv_sigma;
  s.cost += r.squaredNorm();
  if (!linearise) return;
  // C(T ⊕ (ω, v)) = C − Rᵀ Exp(ω)ᵀ v: at 0, dC/dω = 0 and dC/dv = −Rᵀ.
  Mat36 J[3];
  for (int j = 0; j < 3; ++j) {
    J[j].setZero();
    J[j].rightCols<3>() = -t.alpha[j] * inv_sigma * T[t.idx[j]].linear().transpose();
  }
  for (int a = 0; a < 3; ++a) {
    if (col[a] < 0) continue;
    s.b.segment<6>(col[a] * 6) += J[a].transpose() * r;
    for (int c = 0; c < 3; ++c) {
      if (col[c] < 0) continue;
      const Eigen::Matrix<double, 6, 6> blk = J[a].transpose() * J[c];
      for (int y = 0; y < 6; ++y) {
        for (int x = 0; x < 6; ++x) s.h.emplace_back(col[a] * 6 + y, col[c] * 6 + x, blk(y, x));
      }
    }
  }
}

}  // namespace

std::vector<Eigen::Isometry3d> smooth_poses(const StereoIntrinsics& k,
                                            const std::vector<SmoothingFrame>& frames,
                                            const PoseSmoothingParams& params) {
  params.validate();
  check_frames(frames);
  std::vector<Eigen::Isometry3d> T(frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) T[i] = frames[i].T_cam_world;
  const std::vector<Triple> triples = link_triples(frames, params.max_gap);
  // Unknowns: the free frames of at least one triple.
  std::vector<int> col(frames.size(), -1);
  int n = 0;
  for (const Triple& t : triples) {
    for (const std::size_t i : t.idx) {
      if (!frames[i].fixed && col[i] < 0) col[i] = n++;
    }
  }
  if (n == 0) return T;
  const double inv_sigma = 1.0 / params.acceleration_sigma;
  const auto evaluate = [&](const std::vector<Eigen::Isometry3d>& poses, bool linearise) {
    System s;
    s.b = Eigen::VectorXd::Zero(6 * n);
    for (std::size_t i = 0; i < frames.size(); ++i) {
      if (col[i] >= 0) add_observations(k, frames[i], poses[i], params, col[i], s, linearise);
    }
    for (const Triple& t : triples) {
      const int c[3] = {col[t.idx[0]], col[t.idx[1]], col[t.idx[2]]};
      add_triple(t, poses, c, inv_sigma, s, linearise);
    }
    return s;
  };
  for (int it = 0; it < params.iterations; ++it) {
    const System s = evaluate(T, true);
    Eigen::SparseMatrix<double> H(6 * n, 6 * n);
    H.setFromTriplets(s.h.begin(), s.h.end());
    for (int i = 0; i < 6 * n; ++i) H.coeffRef(i, i) += 1e-9;  // a free frame seeing nothing
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
    if (ldlt.info() != Eigen::Success) break;
    const Eigen::VectorXd dx = ldlt.solve(-s.b);
    if (!dx.allFinite()) break;
    bool improved = false;
    for (double step = 1.0; step > 1.0 / 256 && !improved; step *= 0.5) {
      std::vector<Eigen::Isometry3d> next = T;
      for (std::size_t i = 0; i < frames.size(); ++i) {
        if (col[i] >= 0) next[i] = pose_plus(T[i], step * dx.segment<6>(col[i] * 6));
      }
      if (evaluate(next, false).cost < s.cost) {
        T = std::move(next);
        improved = true;
      }
    }
    if (!improved) break;
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (!T[i].matrix().allFinite()) {  // never let a diverged solve leak: the input poses
      for (std::size_t j = 0; j < frames.size(); ++j) T[j] = frames[j].T_cam_world;
      break;
    }
  }
  return T;
}

}  // namespace ds3d::slam
