// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file trajectory_metrics.hpp
/// @brief Absolute trajectory error (ATE) and relative pose error (RPE), numerically identical
/// to the TUM RGB-D benchmark's evaluate_ate.py and evaluate_rpe.py (Sturm et al., IROS 2012).
///
/// ATE: greedy one-to-one timestamp association (associate.py), closed-form rigid alignment of
/// the associated positions (Horn 1987 / Umeyama 1991 via SVD, no scale by default), then the
/// per-match position error. RPE: pairs (i, j) of estimate poses a fixed delta apart, each end
/// matched to the nearest ground-truth stamp, error = inv(inv(E_j) E_i) inv(G_j) G_i.
/// Local ATE (ate_windows()): the same per-window, each window of ground-truth time aligned alone.
/// Statistics are numpy's: rmse, mean, median (mean of the middle two for even n), population
/// std, min, max. Every function here is pure and safe to call concurrently.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <numeric>
#include <random>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"

namespace ds3d {

/// Summary statistics of a list of errors (numpy conventions).
struct ErrorStats {
  double rmse = 0;    ///< sqrt(sum(e^2) / n)
  double mean = 0;    ///< sum(e) / n
  double median = 0;  ///< middle value; mean of the two middle values when n is even
  double std = 0;     ///< population standard deviation (ddof = 0)
  double min = 0;     ///< smallest error
  double max = 0;     ///< largest error
};

/// Statistics of `errors` (all zero for an empty list).
/// @note O(n log n) (the median sorts a copy).
[[nodiscard]] inline ErrorStats compute_error_stats(const std::vector<double>& errors) {
  ErrorStats s;
  if (errors.empty()) return s;
  const auto n = static_cast<double>(errors.size());
  double sum = 0;
  double sum_sq = 0;
  for (const double e : errors) {
    sum += e;
    sum_sq += e * e;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  double var = 0;
  for (const double e : errors) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  const std::size_t m = sorted.size() / 2;
  s.median = (sorted.size() % 2 == 1) ? sorted[m] : (sorted[m - 1] + sorted[m]) / 2.0;
  s.min = sorted.front();
  s.max = sorted.back();
  return s;
}

/// Greedy one-to-one timestamp association, exactly as associate.py: a candidate (a, b) needs
/// `|a - (b + offset)| < max_difference` (strict); candidates are taken in increasing
/// (difference, a, b) order, each stamp at most once.
/// @param first  stamps of the first list (e.g. ground truth, or rgb), sorted ascending, unique
/// @param second stamps of the second list (estimate, or depth), sorted ascending, unique
/// @param offset added to every `second` stamp [s]
/// @param max_difference [s], >= 0
/// @return index pairs (i into first, j into second), sorted by first stamp
/// @throws ds3d::InvalidArgument for unsorted input or a negative/non-finite max_difference.
/// @note O((n + m) log(n + m) + k log k) for k candidates; deterministic.
[[nodiscard]] inline std::vector<std::pair<std::size_t, std::size_t>> associate_timestamps(
    const std::vector<double>& first, const std::vector<double>& second, double offset,
    double max_difference) {
  DS3D_CHECK(std::isfinite(max_difference) && max_difference >= 0,
             "ds3d::associate_timestamps: max_difference must be finite and >= 0 (got ",
             max_difference, ")");
  DS3D_CHECK(std::isfinite(offset), "ds3d::associate_timestamps: offset must be finite (got ",
             offset, ")");
  DS3D_CHECK(
      std::is_sorted(first.begin(), first.end()) && std::is_sorted(second.begin(), second.end()),
      "ds3d::associate_timestamps: stamps must be sorted ascending");
  struct Cand {
    double diff;
    double a;
    double b;
    std::size_t i;
    std::size_t j;
  };
  std::vector<Cand> cands;
  for (std::size_t j = 0; j < second.size(); ++j) {
    const double target = second[j] + offset;
    // Generous window by value, then the exact test of the script on each candidate.
    const double slack = max_difference + 1e-9 * std::max(1.0, std::abs(target));
    auto it = std::lower_bound(first.begin(), first.end(), target - slack);
    for (; it != first.end() && *it <= target + slack; ++it) {
      const double a = *it;
      const double d = std::abs(a - (second[j] + offset));
      if (d < max_difference) {
        cands.push_back({d, a, second[j], static_cast<std::size_t>(it - first.begin()), j});
      }
    }
  }
  std::sort(cands.begin(), cands.end(), [](const Cand& x, const Cand& y) {
    return std::tie(x.diff, x.a, x.b) < std::tie(y.diff, y.a, y.b);
  });
  std::vector<char> used_i(first.size(), 0);
  std::vector<char> used_j(second.size(), 0);
  std::vector<std::pair<std::size_t, std::size_t>> matches;
  for (const Cand& c : cands) {
    if (used_i[c.i] != 0 || used_j[c.j] != 0) continue;
    used_i[c.i] = 1;
    used_j[c.j] = 1;
    matches.emplace_back(c.i, c.j);
  }
  std::sort(matches.begin(), matches.end());
  return matches;
}

/// How the estimate is aligned to the ground truth before ATE.
enum class Alignment : std::uint8_t {
  kSE3,   ///< rotation + translation (evaluate_ate.py, default)
  kSim3,  ///< rotation + translation + scale (Umeyama 1991), for monocular runs
  kNone,  ///< compare raw positions
};

/// Parses "se3", "sim3" or "none". @throws ds3d::InvalidArgument otherwise.
[[nodiscard]] inline Alignment parse_alignment(std::string_view name) {
  if (name == "se3") return Alignment::kSE3;
  if (name == "sim3") return Alignment::kSim3;
  if (name == "none") return Alignment::kNone;
  throw InvalidArgument(detail::concat(
      "ds3d::parse_alignment: alignment must be se3, sim3 or none (got '", name, "')"));
}

/// Options of evaluate_ate(); defaults are evaluate_ate.py's.
struct AteOptions {
  double max_difference = 0.02;           ///< association window [s], >= 0 (strict <)
  double offset = 0.0;                    ///< added to estimate stamps [s]
  double scale = 1.0;                     ///< estimate positions are multiplied by it, > 0
  Alignment alignment = Alignment::kSE3;  ///< se3 (TUM), sim3 or none
  double window = 0.0;  ///< local ATE window [s] of ground-truth time, finite, >= 0; 0 = off
  /// Throws ds3d::InvalidArgument naming the bad field and value.
  void validate() const {
    DS3D_CHECK(std::isfinite(max_difference) && max_difference >= 0,
               "ds3d::evaluate_ate: max_difference must be finite and >= 0 (got ", max_difference,
               ")");
    DS3D_CHECK(std::isfinite(window) && window >= 0,
               "ds3d::evaluate_ate: window must be finite and >= 0 (got ", window, ")");
    DS3D_CHECK(std::isfinite(offset), "ds3d::evaluate_ate: offset must be finite (got ", offset,
               ")");
    DS3D_CHECK(std::isfinite(scale) && scale > 0,
               "ds3d::evaluate_ate: scale must be finite and > 0 (got ", scale, ")");
  }
};

/// One associated ground-truth / estimate pair.
struct AteMatch {
  double t_gt = 0;                                  ///< ground-truth stamp [s]
  double t_est = 0;                                 ///< estimate stamp [s]
  Eigen::Vector3d p_gt = Eigen::Vector3d::Zero();   ///< ground-truth position [m]
  Eigen::Vector3d p_est = Eigen::Vector3d::Zero();  ///< aligned estimate position [m]
  double error = 0;                                 ///< ||p_est - p_gt|| [m]
};

/// One window of the local ATE (see ate_windows()).
struct AteWindow {
  double start = 0;       ///< ground-truth stamp of the window's first pair [s]
  double end = 0;         ///< ground-truth stamp of the window's last pair [s]
  std::size_t pairs = 0;  ///< associated pairs in the window, >= 3
  double rmse = 0;        ///< RMSE after aligning the window on its own [m]
};

/// Result of evaluate_ate(). Errors in metres.
struct AteResult {
  std::size_t compared_pose_pairs = 0;  ///< number of associated pairs
  double rmse = 0;                      ///< [m]
  double mean = 0;                      ///< [m]
  double median = 0;                    ///< [m]
  double std = 0;                       ///< population std [m]
  double min = 0;                       ///< [m]
  double max = 0;                       ///< [m]
  /// Alignment: p_gt ~= scale_factor * rotation * p_est + translation (p_est already multiplied by
  /// AteOptions::scale).
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  ///< [m]
  double scale_factor = 1.0;                              ///< 1 unless Alignment::kSim3
  std::vector<AteMatch> matches;                          ///< sorted by ground-truth stamp
  std::size_t num_gt_poses = 0;    ///< unique, finite ground-truth poses used
  std::size_t num_est_poses = 0;   ///< unique, finite estimate poses used
  std::size_t num_non_finite = 0;  ///< poses skipped (non-finite stamp or position)
  /// Local ATE per AteOptions::window, in time order; empty when the window is 0.
  std::vector<AteWindow> windows;
  double worst_window_rmse = 0;       ///< largest AteWindow::rmse [m]; 0 without windows
  std::size_t num_short_windows = 0;  ///< windows skipped for holding 1 or 2 pairs
  /// The error statistics alone (rmse, mean, median, std, min, max).
  [[nodiscard]] ErrorStats stats() const { return {rmse, mean, median, std, min, max}; }
};

namespace detail {

/// Sorted by stamp, equal stamps keep the later element, non-finite (stamp/pose) dropped.
[[nodiscard]] inline Trajectory normalize_trajectory(const Trajectory& traj, bool need_rotation,
                                                     std::size_t& num_non_finite) {
  std::vector<std::size_t> idx;
  idx.reserve(traj.size());
  for (std::size_t i = 0; i < traj.size(); ++i) {
    const auto& p = traj[i];
    const bool ok = std::isfinite(p.timestamp) && p.T_world_cam.translation().allFinite() &&
                    (!need_rotation || p.T_world_cam.linear().allFinite());
    if (ok) {
      idx.push_back(i);
    } else {
      ++num_non_finite;
    }
  }
  std::stable_sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) {
    return traj[a].timestamp < traj[b].timestamp;
  });
  Trajectory out;
  out.reserve(idx.size());
  for (std::size_t k = 0; k < idx.size(); ++k) {
    if (k + 1 < idx.size() && traj[idx[k + 1]].timestamp == traj[idx[k]].timestamp) continue;
    out.push_back(traj[idx[k]]);
  }
  return out;
}

/// True when every statistic is finite.
[[nodiscard]] inline bool all_finite(const ErrorStats& s) {
  return std::isfinite(s.rmse) && std::isfinite(s.mean) && std::isfinite(s.median) &&
         std::isfinite(s.std) && std::isfinite(s.min) && std::isfinite(s.max);
}

/// Largest |coordinate| of a column of `p` and that column (0 for an empty matrix).
[[nodiscard]] inline std::pair<double, Eigen::Index> largest_coordinate(const Eigen::Matrix3Xd& p) {
  std::pair<double, Eigen::Index> best{0.0, 0};
  for (Eigen::Index k = 0; k < p.cols(); ++k) {
    const double a = p.col(k).cwiseAbs().maxCoeff();
    if (!(a <= best.first)) best = {a, k};
  }
  return best;
}

/// Squared errors of positions beyond ~1e154 m overflow, so statistics would come out as inf or
/// NaN; this names the position responsible instead. `pg`, `pe`: associated positions, columns
/// in match order; `stamp(k, estimate)`: the stamp of match k.
template <class Stamp>
[[noreturn]] void throw_non_finite_errors(const char* function, const char* what, double value,
                                          const Eigen::Matrix3Xd& pg, const Eigen::Matrix3Xd& pe,
                                          const Stamp& stamp) {
  const auto [ag, kg] = largest_coordinate(pg);
  const auto [ae, ke] = largest_coordinate(pe);
  const bool est = !(ae <= ag);
  throw InvalidArgument(concat(function, ": ", what, " is not finite (got ", value,
                               "): ", est ? "estimate" : "ground-truth", " position coordinate ",
                               est ? ae : ag, " at stamp ", stamp(est ? ke : kg, est),
                               " is beyond the supported range (squared errors must stay "
                               "finite, |coordinate| below about 1e150 m)"));
}

[[nodiscard]] inline std::vector<double> stamps_of(const Trajectory& t) {
  std::vector<double> s(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) s[i] = t[i].timestamp;
  return s;
}

}  // namespace detail

/// Closed-form alignment of `model` onto `data` (3 x n each): finds R, t (and scale c for
/// with_scale) minimising sum ||c R m_i + t - d_i||^2. Rigid case exactly as evaluate_ate.py's
/// align(): W = sum (m_i - m)(d_i - d)^T, U S Vh = svd(W^T), R = U diag(1,1,±1) Vh.
/// Scale per Umeyama (1991), Eq. 42. @return {R, t, c}.
inline std::tuple<Eigen::Matrix3d, Eigen::Vector3d, double> align_positions(
    const Eigen::Matrix3Xd& model, const Eigen::Matrix3Xd& data, bool with_scale) {
  const Eigen::Vector3d mean_m = model.rowwise().mean();
  const Eigen::Vector3d mean_d = data.rowwise().mean();
  const Eigen::Matrix3Xd mz = model.colwise() - mean_m;
  const Eigen::Matrix3Xd dz = data.colwise() - mean_d;
  const Eigen::Matrix3d w = mz * dz.transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(w.transpose(),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d u = svd.matrixU();
  const Eigen::Matrix3d vh = svd.matrixV().transpose();
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
  if (u.determinant() * vh.determinant() < 0) s(2, 2) = -1;
  const Eigen::Matrix3d r = u * s * vh;
  double c = 1.0;
  if (with_scale) {
    const double var_m = mz.squaredNorm();
    if (var_m > 0) c = (svd.singularValues().asDiagonal() * s).trace() / var_m;
  }
  const Eigen::Vector3d t = mean_d - c * r * mean_m;
  return {r, t, c};
}

/// ate_windows() result; the fields are copied into AteResult.
struct AteWindowResult {
  std::vector<AteWindow> windows;     ///< windows with >= 3 pairs, in time order
  double worst_window_rmse = 0;       ///< largest rmse of `windows` [m]; 0 when empty
  std::size_t num_short_windows = 0;  ///< windows with 1 or 2 pairs (skipped)
};

/// Local ATE: the matches of `r` (ground-truth time order) are cut into consecutive windows
/// [t0 + k w, t0 + (k+1) w) of ground-truth time, t0 = the first match's stamp; each window with
/// at least 3 pairs is aligned on its own (align_positions(), rigid or similarity per
/// `alignment`; kNone: no alignment) and its RMSE computed. Re-aligning the globally aligned
/// positions equals aligning the raw ones, since rigid and similarity transforms form a group.
/// A local catastrophe (a few seconds of drift) shows here while the global RMSE smears it out.
/// @param r         an evaluate_ate() result (only `matches` is read)
/// @param window    window length w [s], finite, >= 0; 0 gives an empty result
/// @param alignment alignment of each window, normally the one of the global ATE
/// @return the windows with >= 3 pairs, the worst RMSE, the count of windows with 1 or 2 pairs
///         (time spans without any pair are neither listed nor counted)
/// @throws ds3d::InvalidArgument for a negative or non-finite window.
/// @note O(n) for n matches (one 3x3 SVD per window); deterministic; finite for finite matches.
[[nodiscard]] inline AteWindowResult ate_windows(const AteResult& r, double window,
                                                 Alignment alignment) {
  DS3D_CHECK(std::isfinite(window) && window >= 0,
             "ds3d::ate_windows: window must be finite and >= 0 (got ", window, ")");
  AteWindowResult out;
  if (window == 0 || r.matches.empty()) return out;
  const double t0 = r.matches.front().t_gt;
  const auto slot = [&](const AteMatch& m) { return std::floor((m.t_gt - t0) / window); };
  for (std::size_t a = 0; a < r.matches.size();) {
    std::size_t b = a + 1;
    while (b < r.matches.size() && slot(r.matches[b]) == slot(r.matches[a])) ++b;
    const auto n = static_cast<Eigen::Index>(b - a);
    if (n < 3) {
      ++out.num_short_windows;
      a = b;
      continue;
    }
    Eigen::Matrix3Xd pg(3, n);
    Eigen::Matrix3Xd pe(3, n);
    for (Eigen::Index k = 0; k < n; ++k) {
      pg.col(k) = r.matches[a + static_cast<std::size_t>(k)].p_gt;
      pe.col(k) = r.matches[a + static_cast<std::size_t>(k)].p_est;
    }
    if (alignment != Alignment::kNone) {
      const auto [rot, trans, c] = align_positions(pe, pg, alignment == Alignment::kSim3);
      pe = (c * rot) * pe;
      pe.colwise() += trans;
    }
    const double sum_sq = (pe - pg).colwise().squaredNorm().sum();
    const double rmse = std::sqrt(sum_sq / static_cast<double>(n));
    out.windows.push_back({r.matches[a].t_gt, r.matches[b - 1].t_gt, b - a, rmse});
    out.worst_window_rmse = std::max(out.worst_window_rmse, rmse);
    a = b;
  }
  return out;
}

/// Absolute trajectory error, as evaluate_ate.py (default options reproduce
/// `evaluate_ate.py GT EST --verbose` to ~1e-15 relative).
/// @param gt  ground truth (any order; equal stamps: the later element wins)
/// @param est estimate (same rules); only positions are used
/// @param options association window, stamp offset, scale, alignment, local ATE window
/// @return statistics in metres, the alignment, every match and (window > 0) the local ATE
///         of ate_windows() with the same alignment
/// @throws ds3d::InvalidArgument for bad options, or when fewer than 3 pairs associate
///         (1 with Alignment::kNone): the alignment is then undefined.
/// @note Non-finite poses are skipped and counted in num_non_finite. O((n+m) log(n+m)).
[[nodiscard]] inline AteResult evaluate_ate(const Trajectory& gt, const Trajectory& est,
                                            const AteOptions& options = {}) {
  options.validate();
  AteResult res;
  const Trajectory g = detail::normalize_trajectory(gt, false, res.num_non_finite);
  const Trajectory e = detail::normalize_trajectory(est, false, res.num_non_finite);
  res.num_gt_poses = g.size();
  res.num_est_poses = e.size();
  const auto matches = associate_timestamps(detail::stamps_of(g), detail::stamps_of(e),
                                            options.offset, options.max_difference);
  const std::size_t min_pairs = options.alignment == Alignment::kNone ? 1 : 3;
  DS3D_CHECK(matches.size() >= min_pairs, "ds3d::evaluate_ate: only ", matches.size(),
             " pose pairs associate (need ", min_pairs, "; ", g.size(), " gt and ", e.size(),
             " estimate poses, max_difference ", options.max_difference, " s, offset ",
             options.offset, " s): wrong files or offset?");
  const auto n = static_cast<Eigen::Index>(matches.size());
  Eigen::Matrix3Xd pg(3, n);
  Eigen::Matrix3Xd pe(3, n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const auto [i, j] = matches[static_cast<std::size_t>(k)];
    pg.col(k) = g[i].T_world_cam.translation();
    pe.col(k) = e[j].T_world_cam.translation() * options.scale;
  }
  if (options.alignment != Alignment::kNone) {
    std::tie(res.rotation, res.translation, res.scale_factor) =
        align_positions(pe, pg, options.alignment == Alignment::kSim3);
  }
  std::vector<double> errors(matches.size());
  res.matches.resize(matches.size());
  for (Eigen::Index k = 0; k < n; ++k) {
    const auto idx = static_cast<std::size_t>(k);
    AteMatch& m = res.matches[idx];
    m.t_gt = g[matches[idx].first].timestamp;
    m.t_est = e[matches[idx].second].timestamp;
    m.p_gt = pg.col(k);
    m.p_est = res.scale_factor * (res.rotation * pe.col(k)) + res.translation;
    m.error = (m.p_est - m.p_gt).norm();
    errors[idx] = m.error;
  }
  res.compared_pose_pairs = matches.size();
  const ErrorStats s = compute_error_stats(errors);
  res.rmse = s.rmse;
  res.mean = s.mean;
  res.median = s.median;
  res.std = s.std;
  res.min = s.min;
  res.max = s.max;
  if (options.window > 0) {
    AteWindowResult w = ate_windows(res, options.window, options.alignment);
    res.windows = std::move(w.windows);
    res.worst_window_rmse = w.worst_window_rmse;
    res.num_short_windows = w.num_short_windows;
  }
  const std::pair<const char*, double> checked[] = {
      {"rmse", res.rmse},
      {"std", res.std},
      {"max", res.max},
      {"worst window rmse", res.worst_window_rmse},
      {"alignment scale", res.scale_factor},
      {"alignment translation norm", res.translation.norm()},
      {"alignment rotation sum", res.rotation.sum()}};
  for (const auto& [what, value] : checked) {
    if (std::isfinite(value)) continue;
    detail::throw_non_finite_errors("ds3d::evaluate_ate", what, value, pg, pe,
                                    [&](Eigen::Index k, bool of_estimate) {
                                      const auto& m = res.matches[static_cast<std::size_t>(k)];
                                      return of_estimate ? m.t_est : m.t_gt;
                                    });
  }
  return res;
}

// ---------------------------------------------------------------------------------------------
// RPE

/// Unit of the RPE delta; the index always comes from the estimate.
enum class DeltaUnit : std::uint8_t {
  kSeconds,  ///< "s": estimate stamps
  kFrames,   ///< "f": estimate pose index
  kMeters,   ///< "m": cumulative path length of the estimate
  kRadians,  ///< "rad": cumulative rotation angle of the estimate
  kDegrees,  ///< "deg": the same in degrees
};

/// Parses "s", "f", "m", "rad" or "deg". @throws ds3d::InvalidArgument otherwise.
[[nodiscard]] inline DeltaUnit parse_delta_unit(std::string_view name) {
  if (name == "s") return DeltaUnit::kSeconds;
  if (name == "f") return DeltaUnit::kFrames;
  if (name == "m") return DeltaUnit::kMeters;
  if (name == "rad") return DeltaUnit::kRadians;
  if (name == "deg") return DeltaUnit::kDegrees;
  throw InvalidArgument(detail::concat(
      "ds3d::parse_delta_unit: delta unit must be s, f, m, rad or deg (got '", name, "')"));
}

/// Which relative error is measured.
enum class RpeConvention : std::uint8_t {
  kTum,  ///< evaluate_rpe.py: Err = inv(inv(E_j) E_i) * inv(G_j) G_i
  kEvo,  ///< evo (Grupp 2017) forward: Err = inv(inv(G_i) G_j) * inv(E_i) E_j
};

/// Options of evaluate_rpe(). Defaults: evaluate_rpe.py with --fixed_delta --delta 1
/// --delta_unit s (the script's own default without --fixed_delta is all pairs).
struct RpeOptions {
  bool fixed_delta = true;  ///< false: all ordered pairs (or max_pairs random ones)
  double delta = 1.0;       ///< in delta_unit, finite
  /// Unit of delta: s, f, m, rad or deg (see DeltaUnit).
  DeltaUnit delta_unit = DeltaUnit::kSeconds;
  std::size_t max_pairs = 10000;  ///< 0 = no limit; above it pairs are subsampled
  double offset = 0.0;            ///< added to estimate stamps [s]
  double scale = 1.0;             ///< estimate relative translations are scaled by it, > 0
  /// Error convention: the TUM script's, or evo's (see RpeConvention).
  RpeConvention convention = RpeConvention::kTum;
  std::uint64_t seed = 1;  ///< subsampling RNG (the script uses Python's random)
  /// Throws ds3d::InvalidArgument naming the bad field and value.
  void validate() const {
    DS3D_CHECK(std::isfinite(delta), "ds3d::evaluate_rpe: delta must be finite (got ", delta, ")");
    DS3D_CHECK(std::isfinite(offset), "ds3d::evaluate_rpe: offset must be finite (got ", offset,
               ")");
    DS3D_CHECK(std::isfinite(scale) && scale > 0,
               "ds3d::evaluate_rpe: scale must be finite and > 0 (got ", scale, ")");
  }
};

/// One evaluated pose pair, in evaluate_rpe.py's column order.
struct RpePair {
  double t_est0 = 0;         ///< [s]
  double t_est1 = 0;         ///< [s]
  double t_gt0 = 0;          ///< nearest ground-truth stamp to t_est0 + offset [s]
  double t_gt1 = 0;          ///< [s]
  double trans_error = 0;    ///< [m]
  double rot_error_rad = 0;  ///< [rad]
};

/// Result of evaluate_rpe().
struct RpeResult {
  std::size_t compared_pose_pairs = 0;  ///< pairs evaluated
  ErrorStats translational;             ///< [m]
  ErrorStats rotational;                ///< [deg] (computed in rad, then * 180/pi)
  ErrorStats rotational_rad;            ///< [rad]
  std::vector<RpePair> pairs;           ///< in evaluation order (i ascending for fixed delta)
  bool subsampled = false;              ///< true when more than max_pairs pairs existed
  std::size_t num_non_finite = 0;       ///< poses skipped (non-finite stamp or pose)
};

namespace detail {

/// evaluate_rpe.py's find_closest_index(): binary search keeping the first strictly-closer
/// element it visits (its tie rule is part of the contract).
[[nodiscard]] inline std::size_t find_closest_index(const std::vector<double>& l, double t) {
  std::size_t beginning = 0;
  double difference = std::abs(l[0] - t);
  std::size_t best = 0;
  std::size_t end = l.size();
  while (beginning < end) {
    const std::size_t middle = (end + beginning) / 2;
    if (std::abs(l[middle] - t) < difference) {
      difference = std::abs(l[middle] - t);
      best = middle;
    }
    if (t == l[middle]) return middle;
    if (l[middle] > t) {
      end = middle;
    } else {
      beginning = middle + 1;
    }
  }
  return best;
}

/// ominus(a, b) = inv(a) * b with a rigid inverse.
[[nodiscard]] inline Eigen::Matrix4d ominus(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b) {
  Eigen::Matrix4d inv = Eigen::Matrix4d::Identity();
  inv.topLeftCorner<3, 3>() = a.topLeftCorner<3, 3>().transpose();
  inv.topRightCorner<3, 1>() = -(a.topLeftCorner<3, 3>().transpose() * a.topRightCorner<3, 1>());
  return inv * b;
}

[[nodiscard]] inline double rotation_angle(const Eigen::Matrix4d& t) {
  return std::acos(std::min(1.0, std::max(-1.0, (t.topLeftCorner<3, 3>().trace() - 1.0) / 2.0)));
}

}  // namespace detail

/// Relative pose error, as evaluate_rpe.py (see RpeOptions for its flags).
/// @param gt  ground truth (any order; equal stamps: the later element wins)
/// @param est estimate (same rules)
/// @param options delta, unit, pair mode, convention
/// @return translational [m] and rotational [deg and rad] statistics and every pair
/// @throws ds3d::InvalidArgument for bad options, fewer than 2 poses in either trajectory, or
///         fewer than 2 evaluated pairs (the script raises in both cases).
/// @note Fixed delta: O(n log n), deterministic. Only subsampling (more than max_pairs pairs)
///       uses the seeded RNG; its pairs then differ from the script's (Python's RNG).
[[nodiscard]] inline RpeResult evaluate_rpe(const Trajectory& gt, const Trajectory& est,
                                            const RpeOptions& options = {}) {
  options.validate();
  RpeResult res;
  const Trajectory g = detail::normalize_trajectory(gt, true, res.num_non_finite);
  const Trajectory e = detail::normalize_trajectory(est, true, res.num_non_finite);
  DS3D_CHECK(g.size() >= 2 && e.size() >= 2,
             "ds3d::evaluate_rpe: need >= 2 poses in each "
             "trajectory (got ",
             g.size(), " gt and ", e.size(), " estimate poses)");
  const std::vector<double> sg = detail::stamps_of(g);
  const std::vector<double> se = detail::stamps_of(e);
  std::vector<Eigen::Matrix4d> mg(g.size());
  std::vector<Eigen::Matrix4d> me(e.size());
  for (std::size_t i = 0; i < g.size(); ++i) mg[i] = g[i].T_world_cam.matrix();
  for (std::size_t i = 0; i < e.size(); ++i) me[i] = e[i].T_world_cam.matrix();

  // The script's overlap check: at least 2 distinct estimate stamps map back and forth.
  {
    std::vector<double> returned;
    for (const double t : se) {
      const double tg = sg[detail::find_closest_index(sg, t + options.offset)];
      returned.push_back(se[detail::find_closest_index(se, tg - options.offset)]);
    }
    std::sort(returned.begin(), returned.end());
    const auto distinct = std::unique(returned.begin(), returned.end()) - returned.begin();
    DS3D_CHECK(distinct >= 2,
               "ds3d::evaluate_rpe: the timestamps of ground truth and estimate "
               "barely overlap (wrong files or offset?)");
  }

  const std::size_t n = e.size();
  std::vector<double> index(n);
  switch (options.delta_unit) {
    case DeltaUnit::kSeconds:
      index = se;
      break;
    case DeltaUnit::kFrames:
      for (std::size_t i = 0; i < n; ++i) index[i] = static_cast<double>(i);
      break;
    case DeltaUnit::kMeters:
    case DeltaUnit::kRadians:
    case DeltaUnit::kDegrees: {
      const double k = options.delta_unit == DeltaUnit::kDegrees ? 180.0 / std::numbers::pi : 1.0;
      double sum = 0;
      index[0] = 0;
      for (std::size_t i = 0; i + 1 < n; ++i) {
        const Eigen::Matrix4d motion = detail::ominus(me[i + 1], me[i]);
        sum += options.delta_unit == DeltaUnit::kMeters ? motion.topRightCorner<3, 1>().norm()
                                                        : detail::rotation_angle(motion) * k;
        index[i + 1] = sum;
      }
      break;
    }
  }

  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  std::mt19937_64 rng(options.seed);
  if (!options.fixed_delta) {
    if (options.max_pairs == 0 ||
        static_cast<double>(n) < std::sqrt(static_cast<double>(options.max_pairs))) {
      for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t j = 0; j < n; ++j) pairs.emplace_back(i, j);
      }
    } else {
      std::uniform_int_distribution<std::size_t> pick(0, n - 1);
      for (std::size_t k = 0; k < options.max_pairs; ++k) pairs.emplace_back(pick(rng), pick(rng));
      res.subsampled = true;
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t j = detail::find_closest_index(index, index[i] + options.delta);
      if (j != n - 1) pairs.emplace_back(i, j);
    }
    if (options.max_pairs != 0 && pairs.size() > options.max_pairs) {
      // Sample without replacement (partial Fisher-Yates), then restore the i-order.
      for (std::size_t k = 0; k < options.max_pairs; ++k) {
        std::uniform_int_distribution<std::size_t> pick(k, pairs.size() - 1);
        std::swap(pairs[k], pairs[pick(rng)]);
      }
      pairs.resize(options.max_pairs);
      std::sort(pairs.begin(), pairs.end());
      res.subsampled = true;
    }
  }

  // Median of GT stamp differences, as numpy.median.
  std::vector<double> diffs(sg.size() - 1);
  for (std::size_t i = 0; i + 1 < sg.size(); ++i) diffs[i] = sg[i + 1] - sg[i];
  std::sort(diffs.begin(), diffs.end());
  const std::size_t m = diffs.size() / 2;
  const double gt_interval = diffs.size() % 2 == 1 ? diffs[m] : (diffs[m - 1] + diffs[m]) / 2.0;
  const double gt_max_time_difference = 2 * gt_interval;

  std::vector<double> trans;
  std::vector<double> rot;
  for (const auto& [i, j] : pairs) {
    const double te0 = se[i];
    const double te1 = se[j];
    const std::size_t g0 = detail::find_closest_index(sg, te0 + options.offset);
    const std::size_t g1 = detail::find_closest_index(sg, te1 + options.offset);
    if (std::abs(sg[g0] - (te0 + options.offset)) > gt_max_time_difference ||
        std::abs(sg[g1] - (te1 + options.offset)) > gt_max_time_difference) {
      continue;
    }
    Eigen::Matrix4d err;
    if (options.convention == RpeConvention::kTum) {
      Eigen::Matrix4d erel = detail::ominus(me[j], me[i]);
      erel.topRightCorner<3, 1>() *= options.scale;
      err = detail::ominus(erel, detail::ominus(mg[g1], mg[g0]));
    } else {
      Eigen::Matrix4d erel = detail::ominus(me[i], me[j]);
      erel.topRightCorner<3, 1>() *= options.scale;
      err = detail::ominus(detail::ominus(mg[g0], mg[g1]), erel);
    }
    RpePair p{
        te0, te1, sg[g0], sg[g1], err.topRightCorner<3, 1>().norm(), detail::rotation_angle(err)};
    trans.push_back(p.trans_error);
    rot.push_back(p.rot_error_rad);
    res.pairs.push_back(p);
  }
  DS3D_CHECK(res.pairs.size() >= 2, "ds3d::evaluate_rpe: only ", res.pairs.size(),
             " pose pairs could be matched to the ground truth (need 2)");
  res.compared_pose_pairs = res.pairs.size();
  res.translational = compute_error_stats(trans);
  res.rotational_rad = compute_error_stats(rot);
  const double k = 180.0 / std::numbers::pi;
  const ErrorStats& r = res.rotational_rad;
  res.rotational = {r.rmse * k, r.mean * k, r.median * k, r.std * k, r.min * k, r.max * k};
  if (!detail::all_finite(res.translational) || !detail::all_finite(res.rotational_rad)) {
    Eigen::Matrix3Xd pg(3, static_cast<Eigen::Index>(g.size()));
    Eigen::Matrix3Xd pe(3, static_cast<Eigen::Index>(e.size()));
    for (std::size_t i = 0; i < g.size(); ++i)
      pg.col(static_cast<Eigen::Index>(i)) = mg[i].topRightCorner<3, 1>();
    for (std::size_t i = 0; i < e.size(); ++i) {
      pe.col(static_cast<Eigen::Index>(i)) = me[i].topRightCorner<3, 1>() * options.scale;
    }
    const bool bad_trans = !detail::all_finite(res.translational);
    detail::throw_non_finite_errors("ds3d::evaluate_rpe",
                                    bad_trans ? "translational rmse" : "rotational rmse",
                                    bad_trans ? res.translational.rmse : res.rotational_rad.rmse,
                                    pg, pe, [&](Eigen::Index i, bool of_estimate) {
                                      return (of_estimate ? se : sg)[static_cast<std::size_t>(i)];
                                    });
  }
  return res;
}

}  // namespace ds3d
