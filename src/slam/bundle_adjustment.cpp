// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/bundle_adjustment.hpp"

#include <array>
#include <cmath>
#include <memory>

#include <ceres/ceres.h>
#include <ceres/manifold.h>

#include "ds3d/errors.hpp"

namespace ds3d::slam {
namespace {

using Params7 = std::array<double, 7>;

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  if (theta < 1e-12) {
    Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
    r(0, 1) = -w.z();
    r(0, 2) = w.y();
    r(1, 0) = w.z();
    r(1, 2) = -w.x();
    r(2, 0) = -w.y();
    r(2, 1) = w.x();
    return r;
  }
  return Eigen::AngleAxisd(theta, w / theta).toRotationMatrix();
}

Params7 to_params(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  const Eigen::Vector3d& t = T.translation();
  return {q.x(), q.y(), q.z(), q.w(), t.x(), t.y(), t.z()};
}

Eigen::Isometry3d from_params(const double* x) {
  Eigen::Quaterniond q(x[3], x[0], x[1], x[2]);
  q.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = Eigen::Vector3d(x[4], x[5], x[6]);
  return T;
}

// SO(3)×R³ with the left perturbation of pose_plus. The cost functions return their Jacobian
// with respect to the 6-D tangent in the first six of seven ambient columns (last column zero),
// and PlusJacobian is [I₆; 0], so Ceres' product J_ambient · PlusJacobian is exactly the analytic
// tangent Jacobian.
class PoseManifold final : public ceres::Manifold {
 public:
  [[nodiscard]] int AmbientSize() const override { return 7; }
  [[nodiscard]] int TangentSize() const override { return 6; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    const Vector6d d = Eigen::Map<const Vector6d>(delta);
    const Params7 p = to_params(pose_plus(from_params(x), d));
    std::copy(p.begin(), p.end(), x_plus_delta);
    return true;
  }
  bool PlusJacobian(const double* /*x*/, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> j(jacobian);
    j.setZero();
    j.topRows<6>().setIdentity();
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    const Eigen::Isometry3d ty = from_params(y);
    const Eigen::Isometry3d tx = from_params(x);
    const Eigen::AngleAxisd aa(ty.linear() * tx.linear().transpose());
    const Eigen::Vector3d w = aa.angle() * aa.axis();
    const Eigen::Vector3d v = ty.translation() - so3_exp(w) * tx.translation();
    Eigen::Map<Vector6d> out(y_minus_x);
    out << w, v;
    return true;
  }
  bool MinusJacobian(const double* /*x*/, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> j(jacobian);
    j.setZero();
    j.leftCols<6>().setIdentity();
    return true;
  }
};

// Pose-only: the point is a constant.
class PoseCost final : public ceres::CostFunction {
 public:
  PoseCost(const StereoIntrinsics& k, const Eigen::Vector3d& p, const Observation& obs)
      : k_(k), p_(p), obs_(obs) {
    set_num_residuals(obs.stereo() ? 3 : 2);
    mutable_parameter_block_sizes()->push_back(7);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int dim = num_residuals();
    double jp[18];
    const bool want = jacobians != nullptr && jacobians[0] != nullptr;
    reprojection_residual(k_, from_params(parameters[0]), p_, obs_, residuals, want ? jp : nullptr,
                          nullptr);
    if (want) {
      for (int r = 0; r < dim; ++r) {
        for (int c = 0; c < 6; ++c) jacobians[0][r * 7 + c] = jp[r * 6 + c];
        jacobians[0][r * 7 + 6] = 0.0;
      }
    }
    return true;
  }

 private:
  StereoIntrinsics k_;
  Eigen::Vector3d p_;
  Observation obs_;
};

// CentrePrior: (c − centre) / sigma with c = −Rᵀt; under the left perturbation of pose_plus
// dc/dω = 0 and dc/dv = −Rᵀ.
class CentrePriorCost final : public ceres::SizedCostFunction<3, 7> {
 public:
  explicit CentrePriorCost(const CentrePrior& prior) : prior_(prior) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Isometry3d T = from_params(parameters[0]);
    const Eigen::Vector3d r = (T.inverse().translation() - prior_.centre) / prior_.sigma;
    std::copy(r.data(), r.data() + 3, residuals);
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 3, 7, Eigen::RowMajor>> j(jacobians[0]);
      j.setZero();
      j.block<3, 3>(0, 3) = -T.linear().transpose() / prior_.sigma;
    }
    return true;
  }

 private:
  CentrePrior prior_;
};

// Bundle adjustment: pose (7) and point (3).
class BaCost final : public ceres::CostFunction {
 public:
  BaCost(const StereoIntrinsics& k, const Observation& obs) : k_(k), obs_(obs) {
    set_num_residuals(obs.stereo() ? 3 : 2);
    mutable_parameter_block_sizes()->push_back(7);
    mutable_parameter_block_sizes()->push_back(3);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int dim = num_residuals();
    double jp[18];
    double jx[9];
    const bool want_pose = jacobians != nullptr && jacobians[0] != nullptr;
    const bool want_point = jacobians != nullptr && jacobians[1] != nullptr;
    const Eigen::Vector3d p(parameters[1][0], parameters[1][1], parameters[1][2]);
    reprojection_residual(k_, from_params(parameters[0]), p, obs_, residuals,
                          want_pose ? jp : nullptr, want_point ? jx : nullptr);
    if (want_pose) {
      for (int r = 0; r < dim; ++r) {
        for (int c = 0; c < 6; ++c) jacobians[0][r * 7 + c] = jp[r * 6 + c];
        jacobians[0][r * 7 + 6] = 0.0;
      }
    }
    if (want_point) {
      for (int i = 0; i < dim * 3; ++i) jacobians[1][i] = jx[i];
    }
    return true;
  }

 private:
  StereoIntrinsics k_;
  Observation obs_;
};

ceres::Solver::Options solver_options(int iterations, ceres::LinearSolverType type) {
  ceres::Solver::Options o;
  o.linear_solver_type = type;
  o.max_num_iterations = iterations;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  return o;
}

ceres::Problem::Options problem_options() {
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return po;
}

}  // namespace

Eigen::Isometry3d pose_plus(const Eigen::Isometry3d& T, const Vector6d& delta) {
  const Eigen::Matrix3d dr = so3_exp(delta.head<3>());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  // Re-orthonormalise through a quaternion so that repeated updates stay on SO(3).
  out.linear() = Eigen::Quaterniond(dr * T.linear()).normalized().toRotationMatrix();
  out.translation() = dr * T.translation() + delta.tail<3>();
  return out;
}

int reprojection_residual(const StereoIntrinsics& k, const Eigen::Isometry3d& T_cam_world,
                          const Eigen::Vector3d& p_world, const Observation& obs, double* residual,
                          double* j_pose, double* j_point) {
  const int dim = obs.stereo() ? 3 : 2;
  const Eigen::Vector3d pc = T_cam_world * p_world;
  if (!(pc.z() > 1e-6) || !pc.allFinite()) {
    for (int i = 0; i < dim; ++i) residual[i] = 0.0;
    if (j_pose != nullptr) std::fill(j_pose, j_pose + dim * 6, 0.0);
    if (j_point != nullptr) std::fill(j_point, j_point + dim * 3, 0.0);
    return 0;
  }
  const double s = std::sqrt(obs.inv_sigma2);
  const double iz = 1.0 / pc.z();
  const double iz2 = iz * iz;
  const double u = k.fx * pc.x() * iz + k.cx;
  const double v = k.fy * pc.y() * iz + k.cy;
  residual[0] = s * (obs.pixel.x() - u);
  residual[1] = s * (obs.pixel.y() - v);
  const bool disparity = obs.disparity_inv_sigma2 > 0;
  const double sd = disparity ? std::sqrt(obs.disparity_inv_sigma2) : s;
  if (dim == 3) {
    residual[2] = disparity ? sd * ((obs.pixel.x() - obs.u_right) - k.bf * iz)
                            : s * (obs.u_right - (u - k.bf * iz));
  }
  if (j_pose == nullptr && j_point == nullptr) return dim;
  // d residual / d p_cam = -weight · d prediction / d p_cam
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> jc;
  jc << k.fx * iz, 0.0, -k.fx * pc.x() * iz2,  //
      0.0, k.fy * iz, -k.fy * pc.y() * iz2,    //
      k.fx * iz, 0.0, -k.fx * pc.x() * iz2 + k.bf * iz2;
  if (disparity) jc.row(2) << 0.0, 0.0, -k.bf * iz2;
  jc.topRows<2>() *= -s;
  jc.row(2) *= -sd;
  if (j_pose != nullptr) {
    // d p_cam / d (ω, v) = [-[p_cam]× | I] for the left perturbation.
    Eigen::Matrix<double, 3, 6, Eigen::RowMajor> dp;
    dp << 0.0, pc.z(), -pc.y(), 1.0, 0.0, 0.0,  //
        -pc.z(), 0.0, pc.x(), 0.0, 1.0, 0.0,    //
        pc.y(), -pc.x(), 0.0, 0.0, 0.0, 1.0;
    const Eigen::Matrix<double, 3, 6, Eigen::RowMajor> j = jc * dp;
    std::copy(j.data(), j.data() + dim * 6, j_pose);
  }
  if (j_point != nullptr) {
    const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> j = jc * T_cam_world.linear();
    std::copy(j.data(), j.data() + dim * 3, j_point);
  }
  return dim;
}

double reprojection_chi2(const StereoIntrinsics& k, const Eigen::Isometry3d& T_cam_world,
                         const Eigen::Vector3d& p_world, const Observation& obs, bool* in_front) {
  double r[3] = {0, 0, 0};
  const int dim = reprojection_residual(k, T_cam_world, p_world, obs, r, nullptr, nullptr);
  if (in_front != nullptr) *in_front = dim > 0;
  return r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
}

void PoseOptimizerParams::validate() const {
  constexpr const char* f = "ds3d::slam::PoseOptimizerParams";
  DS3D_CHECK(rounds >= 1, f, ": rounds must be >= 1 (got ", rounds, ")");
  DS3D_CHECK(iterations >= 1, f, ": iterations must be >= 1 (got ", iterations, ")");
  DS3D_CHECK(std::isfinite(chi2_mono) && chi2_mono > 0, f, ": chi2_mono must be > 0 (got ",
             chi2_mono, ")");
  DS3D_CHECK(std::isfinite(chi2_stereo) && chi2_stereo > 0, f, ": chi2_stereo must be > 0 (got ",
             chi2_stereo, ")");
}

void LocalBaParams::validate() const {
  constexpr const char* f = "ds3d::slam::LocalBaParams";
  DS3D_CHECK(iterations_first >= 1, f, ": iterations_first must be >= 1 (got ", iterations_first,
             ")");
  DS3D_CHECK(iterations_second >= 0, f, ": iterations_second must be >= 0 (got ", iterations_second,
             ")");
  DS3D_CHECK(std::isfinite(chi2_mono) && chi2_mono > 0, f, ": chi2_mono must be > 0 (got ",
             chi2_mono, ")");
  DS3D_CHECK(std::isfinite(chi2_stereo) && chi2_stereo > 0, f, ": chi2_stereo must be > 0 (got ",
             chi2_stereo, ")");
}

PoseOptimizationResult optimize_pose(const StereoIntrinsics& k, const Eigen::Isometry3d& initial,
                                     const std::vector<Eigen::Vector3d>& points,
                                     const std::vector<Observation>& observations,
                                     const PoseOptimizerParams& params, const CentrePrior& prior) {
  params.validate();
  DS3D_CHECK(points.size() == observations.size(), "ds3d::slam::optimize_pose: ", points.size(),
             " points but ", observations.size(), " observations");
  DS3D_CHECK(std::isfinite(prior.sigma) && prior.sigma >= 0,
             "ds3d::slam::optimize_pose: prior.sigma must be finite and >= 0 (got ", prior.sigma,
             ")");
  DS3D_CHECK(std::isfinite(prior.huber) && prior.huber >= 0,
             "ds3d::slam::optimize_pose: prior.huber must be finite and >= 0 (got ", prior.huber,
             ")");
  DS3D_CHECK(prior.sigma == 0 || prior.centre.allFinite(),
             "ds3d::slam::optimize_pose: prior.centre must be finite (got ",
             prior.centre.transpose(), ")");
  const std::size_t n = points.size();
  PoseOptimizationResult result;
  result.T_cam_world = initial;
  result.inlier.assign(n, 0);
  if (n < 3 || !initial.matrix().allFinite()) return result;

  std::vector<std::unique_ptr<PoseCost>> costs;
  costs.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    costs.push_back(std::make_unique<PoseCost>(k, points[i], observations[i]));
  PoseManifold manifold;
  CentrePriorCost prior_cost(prior);
  ceres::HuberLoss prior_loss(prior.huber > 0 ? prior.huber : 1.0);
  ceres::HuberLoss huber_mono(std::sqrt(params.chi2_mono));
  ceres::HuberLoss huber_stereo(std::sqrt(params.chi2_stereo));
  Params7 x = to_params(initial);
  std::vector<std::uint8_t> inl(n, 1);
  const auto options = solver_options(params.iterations, ceres::DENSE_NORMAL_CHOLESKY);
  for (int round = 0; round < params.rounds; ++round) {
    ceres::Problem problem(problem_options());
    problem.AddParameterBlock(x.data(), 7, &manifold);
    const bool robust = round < params.rounds - 1;
    int used = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (inl[i] == 0) continue;
      ceres::LossFunction* loss = nullptr;
      if (robust) loss = observations[i].stereo() ? &huber_stereo : &huber_mono;
      problem.AddResidualBlock(costs[i].get(), loss, x.data());
      ++used;
    }
    if (used < 3) break;
    if (prior.sigma > 0) {
      problem.AddResidualBlock(&prior_cost, prior.huber > 0 ? &prior_loss : nullptr, x.data());
    }
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    const Eigen::Isometry3d T = from_params(x.data());
    if (!T.matrix().allFinite()) break;
    result.T_cam_world = T;
    for (std::size_t i = 0; i < n; ++i) {
      bool front = false;
      const double chi2 = reprojection_chi2(k, T, points[i], observations[i], &front);
      const double th = observations[i].stereo() ? params.chi2_stereo : params.chi2_mono;
      inl[i] = static_cast<std::uint8_t>(front && chi2 <= th);
    }
  }
  result.inlier = inl;
  result.num_inliers = 0;
  for (const auto f : inl) result.num_inliers += f;
  return result;
}

LocalBaResult local_bundle_adjustment(const StereoIntrinsics& k,
                                      const std::vector<Eigen::Isometry3d>& poses,
                                      const std::vector<std::uint8_t>& fixed,
                                      const std::vector<Eigen::Vector3d>& points,
                                      const std::vector<BaObservation>& observations,
                                      const LocalBaParams& params) {
  constexpr const char* fn = "ds3d::slam::local_bundle_adjustment";
  params.validate();
  DS3D_CHECK(poses.size() == fixed.size(), fn, ": ", poses.size(), " poses but ", fixed.size(),
             " fixed flags");
  bool any_fixed = false;
  for (const auto f : fixed) any_fixed = any_fixed || f != 0;
  DS3D_CHECK(any_fixed, fn, ": at least one pose must be fixed (gauge freedom)");
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const auto& o = observations[i];
    DS3D_CHECK(o.keyframe >= 0 && static_cast<std::size_t>(o.keyframe) < poses.size(), fn,
               ": observations[", i, "].keyframe out of range (got ", o.keyframe, ")");
    DS3D_CHECK(o.point >= 0 && static_cast<std::size_t>(o.point) < points.size(), fn,
               ": observations[", i, "].point out of range (got ", o.point, ")");
  }
  std::vector<Params7> x(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) x[i] = to_params(poses[i]);
  std::vector<std::array<double, 3>> p(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    p[i] = {points[i].x(), points[i].y(), points[i].z()};

  std::vector<std::unique_ptr<BaCost>> costs;
  costs.reserve(observations.size());
  for (const auto& o : observations) costs.push_back(std::make_unique<BaCost>(k, o.obs));
  PoseManifold manifold;
  ceres::HuberLoss huber_mono(std::sqrt(params.chi2_mono));
  ceres::HuberLoss huber_stereo(std::sqrt(params.chi2_stereo));

  LocalBaResult result;
  result.outlier.assign(observations.size(), 0);
  auto classify = [&] {
    for (std::size_t i = 0; i < observations.size(); ++i) {
      const auto& o = observations[i];
      bool front = false;
      const double chi2 = reprojection_chi2(
          k, from_params(x[static_cast<std::size_t>(o.keyframe)].data()),
          Eigen::Vector3d(p[static_cast<std::size_t>(o.point)].data()), o.obs, &front);
      const double th = o.obs.stereo() ? params.chi2_stereo : params.chi2_mono;
      result.outlier[i] = static_cast<std::uint8_t>(!front || chi2 > th);
    }
  };
  auto solve = [&](int iterations, bool robust, bool skip_outliers) {
    ceres::Problem problem(problem_options());
    for (std::size_t i = 0; i < x.size(); ++i) {
      problem.AddParameterBlock(x[i].data(), 7, &manifold);
      if (fixed[i] != 0) problem.SetParameterBlockConstant(x[i].data());
    }
    int used = 0;
    for (std::size_t i = 0; i < observations.size(); ++i) {
      if (skip_outliers && result.outlier[i] != 0) continue;
      const auto& o = observations[i];
      ceres::LossFunction* loss = nullptr;
      if (robust) loss = o.obs.stereo() ? &huber_stereo : &huber_mono;
      problem.AddResidualBlock(costs[i].get(), loss, x[static_cast<std::size_t>(o.keyframe)].data(),
                               p[static_cast<std::size_t>(o.point)].data());
      ++used;
    }
    if (used == 0) return;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options(iterations, ceres::DENSE_SCHUR), &problem, &summary);
    if (result.initial_cost == 0.0) result.initial_cost = summary.initial_cost;
    result.final_cost = summary.final_cost;
  };
  const auto x0 = x;
  const auto p0 = p;
  solve(params.iterations_first, true, false);
  classify();
  if (params.iterations_second > 0) solve(params.iterations_second, false, true);
  classify();

  // Never let a diverged solve leak: fall back to the input for any non-finite block.
  result.poses.resize(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Isometry3d T = from_params(x[i].data());
    result.poses[i] = T.matrix().allFinite() ? T : from_params(x0[i].data());
  }
  result.points.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d q(p[i].data());
    result.points[i] = q.allFinite() ? q : Eigen::Vector3d(p0[i].data());
  }
  return result;
}

}  // namespace ds3d::slam
