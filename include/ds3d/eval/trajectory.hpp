// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file trajectory.hpp
/// @brief Camera trajectories in the TUM RGB-D format: `timestamp tx ty tz qx qy qz qw`.
///
/// Reading follows the TUM benchmark scripts (J. Sturm et al., "A Benchmark for the Evaluation
/// of RGB-D SLAM Systems", IROS 2012; evaluate_ate.py / evaluate_rpe.py) line for line:
/// universal newlines; ',' and TAB act as spaces; a line is skipped when it is empty or its
/// first character is '#'; numbers use Python's float() grammar; a timestamp that occurs twice
/// keeps its later line; the result is sorted by timestamp. Poses are camera-to-world
/// (`p_world = T_world_cam * p_cam`; the translation is the camera centre in the world).

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <Eigen/Geometry>

#include "ds3d/detail/tum_text.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// One timestamped camera pose.
struct TimedPose {
  double timestamp = 0;                                           ///< [s], usually Unix epoch
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< camera-to-world
};

/// A camera trajectory (camera-to-world, TUM convention). Readers return it sorted by timestamp
/// with unique timestamps; evaluation functions accept any order (see trajectory_metrics.hpp).
using Trajectory = std::vector<TimedPose>;

/// Options of parse_tum_trajectory() / read_tum_file().
struct TumReadOptions {
  /// false (default, evaluate_rpe.py's rule): lines whose quaternion is exactly 0 0 0 0 are
  /// skipped. true (evaluate_ate.py, which reads positions only): they are kept with an
  /// identity rotation.
  bool keep_zero_quaternion = false;
};

/// What parse_tum_trajectory() read, with counts of what it dropped.
struct TumReadResult {
  Trajectory trajectory;                ///< sorted by timestamp, unique timestamps
  std::size_t num_lines = 0;            ///< data lines parsed (comments/blank lines excluded)
  std::size_t num_duplicates = 0;       ///< lines replaced by a later line with the same stamp
  std::size_t num_zero_quaternion = 0;  ///< lines skipped for a 0 0 0 0 quaternion
  std::size_t num_non_finite = 0;       ///< lines skipped for a NaN or infinite value
  std::size_t first_zero_quaternion_line = 0;  ///< line number of the first such line (0: none)
  std::size_t first_non_finite_line = 0;       ///< line number of the first such line (0: none)
};

namespace detail {

/// max |RᵀR − I|: how far a 3×3 matrix is from orthonormal (0 for a rotation or reflection).
[[nodiscard]] inline double orthonormality_error(const Eigen::Matrix3d& r) {
  return (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
}

/// Rotation matrix exactly as evaluate_rpe.py's transform44(): q scaled by sqrt(2/|q|^2), then
/// the outer product; identity when |q|^2 < 4*eps. q = (qx, qy, qz, qw), not necessarily unit.
[[nodiscard]] inline Eigen::Matrix3d tum_quaternion_to_matrix(double qx, double qy, double qz,
                                                              double qw) {
  double q[4] = {qx, qy, qz, qw};
  const double nq = qx * qx + qy * qy + qz * qz + qw * qw;
  if (nq < 4.0 * std::numeric_limits<double>::epsilon()) return Eigen::Matrix3d::Identity();
  const double s = std::sqrt(2.0 / nq);
  for (double& v : q) v *= s;
  double o[4][4];
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) o[i][j] = q[i] * q[j];
  }
  Eigen::Matrix3d r;
  r << 1.0 - o[1][1] - o[2][2], o[0][1] - o[2][3], o[0][2] + o[1][3],  //
      o[0][1] + o[2][3], 1.0 - o[0][0] - o[2][2], o[1][2] - o[0][3],   //
      o[0][2] - o[1][3], o[1][2] + o[0][3], 1.0 - o[0][0] - o[1][1];
  return r;
}

/// Shortest decimal that reads back as the same double.
inline void append_double(std::string& out, double v) {
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, res.ptr);
}

}  // namespace detail

/// Parses TUM trajectory text (see the file comment for the rules).
/// @param text    whole file content
/// @param options zero-quaternion policy
/// @param source  name used in error messages (file name)
/// @return the trajectory and counts; lines with a NaN/inf value are skipped and counted (as
///         evaluate_rpe.py does), so no non-finite value reaches the trajectory.
/// @throws ds3d::IoError naming source and line for a token that is not a number or a line with
///         fewer than 8 numbers (the TUM scripts crash on these).
/// @note O(n log n); deterministic.
[[nodiscard]] inline TumReadResult parse_tum_trajectory(std::string_view text,
                                                        const TumReadOptions& options = {},
                                                        std::string_view source = "<text>") {
  struct Row {
    double v[8];
    std::size_t order;
  };
  std::vector<Row> rows;
  TumReadResult res;
  for (const auto& line : detail::split_tum_lines(text)) {
    if (line.tokens.empty()) continue;  // only spaces: skipped (the scripts crash here)
    DS3D_CHECK_AS(IoError, line.tokens.size() >= 8, "ds3d::read_tum_trajectory: ", source, " line ",
                  line.number, ": expected 8 numbers 'timestamp tx ty tz qx qy qz qw' (got ",
                  line.tokens.size(), " tokens)");
    Row row{};
    row.order = rows.size();
    for (std::size_t k = 0; k < 8; ++k) {
      const auto v = detail::parse_py_float(line.tokens[k]);
      DS3D_CHECK_AS(IoError, v.has_value(), "ds3d::read_tum_trajectory: ", source, " line ",
                    line.number, ": '", line.tokens[k], "' is not a number");
      row.v[k] = *v;
    }
    ++res.num_lines;
    // ATE reading (positions only) still sees zero-quaternion lines; RPE skips them.
    if (row.v[4] == 0 && row.v[5] == 0 && row.v[6] == 0 && row.v[7] == 0 &&
        !options.keep_zero_quaternion) {
      if (res.num_zero_quaternion++ == 0) res.first_zero_quaternion_line = line.number;
      continue;
    }
    if (!std::all_of(std::begin(row.v), std::end(row.v),
                     [](double x) { return std::isfinite(x); })) {
      if (res.num_non_finite++ == 0) res.first_non_finite_line = line.number;
      continue;
    }
    rows.push_back(row);
  }
  // Sort by stamp, later line last; keep the last of each equal-stamp run (dict semantics).
  std::stable_sort(rows.begin(), rows.end(),
                   [](const Row& a, const Row& b) { return a.v[0] < b.v[0]; });
  res.trajectory.reserve(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (i + 1 < rows.size() && rows[i + 1].v[0] == rows[i].v[0]) {
      ++res.num_duplicates;
      continue;
    }
    const double* v = rows[i].v;
    TimedPose p;
    p.timestamp = v[0];
    p.T_world_cam.linear() = detail::tum_quaternion_to_matrix(v[4], v[5], v[6], v[7]);
    p.T_world_cam.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    res.trajectory.push_back(p);
  }
  return res;
}

/// Reads a TUM trajectory file with explicit options and counts.
/// @throws ds3d::IoError when the file cannot be read or a line is malformed (file and line named).
[[nodiscard]] inline TumReadResult read_tum_file(const std::filesystem::path& path,
                                                 const TumReadOptions& options = {}) {
  const std::string text = detail::read_text_file(path, "ds3d::read_tum_trajectory");
  return parse_tum_trajectory(text, options, path.string());
}

/// Reads a TUM trajectory file (evaluate_rpe.py rules: zero-quaternion and NaN lines skipped).
/// @param path file in TUM format
/// @return poses sorted by timestamp, unique timestamps, rotations orthonormal
/// @throws ds3d::IoError when the file is missing/unreadable or a line is malformed.
/// @note O(n log n).
[[nodiscard]] inline Trajectory read_tum_trajectory(const std::filesystem::path& path) {
  return read_tum_file(path).trajectory;
}

/// Formats a trajectory as TUM text: one `timestamp tx ty tz qx qy qz qw` line per pose, in the
/// given order, with the shortest round-trip decimal of every value (reading it back gives the
/// same doubles, up to quaternion normalisation).
/// @throws ds3d::InvalidArgument for a non-finite timestamp or pose (names the index).
[[nodiscard]] inline std::string format_tum_trajectory(const Trajectory& traj) {
  std::string out = "# timestamp tx ty tz qx qy qz qw\n";
  out.reserve(out.size() + traj.size() * 120);
  for (std::size_t i = 0; i < traj.size(); ++i) {
    const TimedPose& p = traj[i];
    DS3D_CHECK(std::isfinite(p.timestamp) && p.T_world_cam.matrix().allFinite(),
               "ds3d::write_tum_trajectory: pose ", i, " (timestamp ", p.timestamp,
               ") is not finite");
    const Eigen::Quaterniond q(p.T_world_cam.linear());
    const Eigen::Vector3d t = p.T_world_cam.translation();
    const double vals[8] = {p.timestamp, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
    for (int k = 0; k < 8; ++k) {
      if (k > 0) out += ' ';
      detail::append_double(out, vals[k]);
    }
    out += '\n';
  }
  return out;
}

/// Writes a TUM trajectory file: content goes to a temporary file beside `path`, which is then
/// renamed over it, so an interrupted run never leaves a truncated file.
/// @param path destination; its directory must exist
/// @param traj poses, written in the given order
/// @throws ds3d::InvalidArgument for a non-finite pose; ds3d::IoError when writing fails.
inline void write_tum_trajectory(const std::filesystem::path& path, const Trajectory& traj) {
  detail::write_file_atomically(path, format_tum_trajectory(traj), "ds3d::write_tum_trajectory");
}

}  // namespace ds3d
