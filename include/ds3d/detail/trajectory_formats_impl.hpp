// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bodies of trajectory_formats.hpp: KITTI and EuRoC readers and writers, format detection.
#pragma once

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "ds3d/detail/tum_text.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

namespace detail {

/// One parsed pose line before sorting: stamp, pose and the line's order in the file.
struct PoseRow {
  double timestamp;
  Eigen::Isometry3d T_world_cam;
  std::size_t order;
};

/// Sorts rows by stamp (stable) and keeps the last of each equal-stamp run, as TUM reading does.
inline void finish_pose_rows(std::vector<PoseRow>& rows, TumReadResult& res) {
  std::stable_sort(rows.begin(), rows.end(),
                   [](const PoseRow& a, const PoseRow& b) { return a.timestamp < b.timestamp; });
  res.trajectory.reserve(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (i + 1 < rows.size() && rows[i + 1].timestamp == rows[i].timestamp) {
      ++res.num_duplicates;
      continue;
    }
    res.trajectory.push_back({rows[i].timestamp, rows[i].T_world_cam});
  }
}

/// A token of digits with an optional sign, as an int64 (nullopt otherwise or on overflow).
[[nodiscard]] inline std::optional<std::int64_t> parse_int64(std::string_view tok) {
  std::string_view t = tok;
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  std::int64_t v = 0;
  const auto res = std::from_chars(t.data(), t.data() + t.size(), v);
  if (t.empty() || res.ec != std::errc() || res.ptr != t.data() + t.size()) return std::nullopt;
  return v;
}

/// Seconds of an integer number of nanoseconds, rounded once.
[[nodiscard]] inline double ns_to_seconds(std::int64_t ns) {
  const std::int64_t s = ns / 1000000000;
  const std::int64_t f = ns % 1000000000;
  return static_cast<double>(s) + static_cast<double>(f) * 1e-9;
}

inline void check_finite_pose(const TimedPose& p, std::size_t i, const char* function) {
  DS3D_CHECK(std::isfinite(p.timestamp) && p.T_world_cam.matrix().allFinite(), function, ": pose ",
             i, " (timestamp ", p.timestamp, ") is not finite");
}

[[nodiscard]] inline std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace detail

inline const char* to_string(TrajectoryFormat f) noexcept {
  switch (f) {
    case TrajectoryFormat::kTum:
      return "tum";
    case TrajectoryFormat::kKitti:
      return "kitti";
    case TrajectoryFormat::kEuroc:
      return "euroc";
  }
  return "tum";
}

inline TrajectoryFormat parse_trajectory_format(std::string_view name) {
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "kitti") return TrajectoryFormat::kKitti;
  if (name == "euroc") return TrajectoryFormat::kEuroc;
  throw InvalidArgument(detail::concat("ds3d::parse_trajectory_format: format must be tum, kitti ",
                                       "or euroc (got '", name, "')"));
}

inline TrajectoryFormat detect_trajectory_format(const std::filesystem::path& path,
                                                 std::string_view text) {
  if (detail::lower(path.extension().string()) == ".csv") return TrajectoryFormat::kEuroc;
  if (text.find("p_RS_R_x") != std::string_view::npos) return TrajectoryFormat::kEuroc;
  for (const auto& line : detail::split_tum_lines(text)) {
    if (line.tokens.empty()) continue;
    if (line.tokens.size() == 12) return TrajectoryFormat::kKitti;
    // The raw line: its first token is a view into `text`.
    const std::size_t begin = static_cast<std::size_t>(line.tokens.front().data() - text.data());
    const std::size_t end = text.find_first_of("\r\n", begin);
    const std::string_view raw =
        text.substr(begin, end == std::string_view::npos ? end : end - begin);
    if (raw.find(',') != std::string_view::npos && line.tokens.size() >= 8 &&
        detail::parse_int64(line.tokens.front())) {
      return TrajectoryFormat::kEuroc;
    }
    return TrajectoryFormat::kTum;
  }
  return TrajectoryFormat::kTum;
}

inline TumReadResult parse_kitti_trajectory(std::string_view text,
                                            const std::vector<double>* timestamps,
                                            std::string_view source) {
  constexpr const char* kFn = "ds3d::read_kitti_trajectory: ";
  std::vector<detail::PoseRow> rows;
  TumReadResult res;
  for (const auto& line : detail::split_tum_lines(text)) {
    if (line.tokens.empty()) continue;
    DS3D_CHECK_AS(IoError, line.tokens.size() == 12, kFn, source, " line ", line.number,
                  ": expected 12 numbers (a 3x4 row-major pose [R | t]), got ", line.tokens.size());
    double v[12];
    for (std::size_t k = 0; k < 12; ++k) {
      const auto x = detail::parse_py_float(line.tokens[k]);
      DS3D_CHECK_AS(IoError, x.has_value(), kFn, source, " line ", line.number, ": '",
                    line.tokens[k], "' is not a number");
      v[k] = *x;
    }
    const std::size_t index = res.num_lines++;
    double t = static_cast<double>(index);
    if (timestamps != nullptr && index < timestamps->size()) t = (*timestamps)[index];
    if (!std::all_of(std::begin(v), std::end(v), [](double x) { return std::isfinite(x); })) {
      if (res.num_non_finite++ == 0) res.first_non_finite_line = line.number;
      continue;
    }
    Eigen::Matrix3d r;
    r << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    const double off = detail::orthonormality_error(r);
    DS3D_CHECK_AS(IoError, off <= 1e-3 && r.determinant() > 0, kFn, source, " line ", line.number,
                  ": the 3x3 part is not a rotation (max |R^T R - I| = ", off, ", det ",
                  r.determinant(), ")");
    detail::PoseRow row{t, Eigen::Isometry3d::Identity(), rows.size()};
    row.T_world_cam.linear() = Eigen::Quaterniond(r).normalized().toRotationMatrix();
    row.T_world_cam.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
    rows.push_back(row);
  }
  DS3D_CHECK_AS(IoError, timestamps == nullptr || timestamps->size() == res.num_lines, kFn, source,
                ": ", res.num_lines, " pose lines but ",
                timestamps == nullptr ? 0 : timestamps->size(), " timestamps");
  detail::finish_pose_rows(rows, res);
  return res;
}

inline TumReadResult parse_euroc_trajectory(std::string_view text, const TumReadOptions& options,
                                            std::string_view source) {
  constexpr const char* kFn = "ds3d::read_euroc_trajectory: ";
  std::vector<detail::PoseRow> rows;
  TumReadResult res;
  for (const auto& line : detail::split_tum_lines(text)) {
    if (line.tokens.empty()) continue;
    DS3D_CHECK_AS(IoError, line.tokens.size() >= 8, kFn, source, " line ", line.number,
                  ": expected at least 8 values 'timestamp [ns], px, py, pz [m], qw, qx, qy, qz', "
                  "got ",
                  line.tokens.size());
    double v[8];
    for (std::size_t k = 0; k < 8; ++k) {
      const auto x = detail::parse_py_float(line.tokens[k]);
      DS3D_CHECK_AS(IoError, x.has_value(), kFn, source, " line ", line.number, ": '",
                    line.tokens[k], "' is not a number");
      v[k] = *x;
    }
    const auto ns = detail::parse_int64(line.tokens[0]);
    v[0] = ns ? detail::ns_to_seconds(*ns) : v[0] * 1e-9;
    ++res.num_lines;
    if (v[4] == 0 && v[5] == 0 && v[6] == 0 && v[7] == 0 && !options.keep_zero_quaternion) {
      if (res.num_zero_quaternion++ == 0) res.first_zero_quaternion_line = line.number;
      continue;
    }
    if (!std::all_of(std::begin(v), std::end(v), [](double x) { return std::isfinite(x); })) {
      if (res.num_non_finite++ == 0) res.first_non_finite_line = line.number;
      continue;
    }
    detail::PoseRow row{v[0], Eigen::Isometry3d::Identity(), rows.size()};
    // TUM's quaternion-to-matrix rule, with EuRoC's w-first order mapped to (x, y, z, w).
    row.T_world_cam.linear() = detail::tum_quaternion_to_matrix(v[5], v[6], v[7], v[4]);
    row.T_world_cam.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    rows.push_back(row);
  }
  detail::finish_pose_rows(rows, res);
  return res;
}

inline std::vector<double> parse_timestamp_list(std::string_view text, std::string_view source) {
  std::vector<double> out;
  for (const auto& line : detail::split_tum_lines(text)) {
    if (line.tokens.empty()) continue;
    const auto t = detail::parse_py_float(line.tokens.front());
    DS3D_CHECK_AS(IoError, t.has_value() && std::isfinite(*t),
                  "ds3d::read_timestamp_list: ", source, " line ", line.number, ": '",
                  line.tokens.front(), "' is not a finite number");
    out.push_back(*t);
  }
  return out;
}

inline TrajectoryReadResult read_trajectory(const std::filesystem::path& path,
                                            const TrajectoryReadOptions& options) {
  const std::string text = detail::read_text_file(path, "ds3d::read_trajectory");
  TrajectoryReadResult res;
  res.format = options.format.value_or(detect_trajectory_format(path, text));
  const TumReadOptions tum{.keep_zero_quaternion = options.keep_zero_quaternion};
  switch (res.format) {
    case TrajectoryFormat::kTum:
      static_cast<TumReadResult&>(res) = parse_tum_trajectory(text, tum, path.string());
      break;
    case TrajectoryFormat::kKitti:
      static_cast<TumReadResult&>(res) = parse_kitti_trajectory(
          text, options.kitti_timestamps ? &*options.kitti_timestamps : nullptr, path.string());
      break;
    case TrajectoryFormat::kEuroc:
      static_cast<TumReadResult&>(res) = parse_euroc_trajectory(text, tum, path.string());
      break;
  }
  return res;
}

inline std::vector<double> read_timestamp_list(const std::filesystem::path& path) {
  return parse_timestamp_list(detail::read_text_file(path, "ds3d::read_timestamp_list"),
                              path.string());
}

inline std::string format_kitti_trajectory(const Trajectory& traj) {
  std::string out;
  out.reserve(traj.size() * 200);
  for (std::size_t i = 0; i < traj.size(); ++i) {
    detail::check_finite_pose(traj[i], i, "ds3d::write_kitti_trajectory");
    const Eigen::Matrix4d m = traj[i].T_world_cam.matrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        if (r + c > 0) out += ' ';
        detail::append_double(out, m(r, c));
      }
    }
    out += '\n';
  }
  return out;
}

inline std::string format_euroc_trajectory(const Trajectory& traj) {
  std::string out =
      "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],"
      "q_RS_z []\n";
  out.reserve(out.size() + traj.size() * 120);
  for (std::size_t i = 0; i < traj.size(); ++i) {
    const TimedPose& p = traj[i];
    detail::check_finite_pose(p, i, "ds3d::write_euroc_trajectory");
    DS3D_CHECK(std::abs(p.timestamp) < 9.2e9, "ds3d::write_euroc_trajectory: pose ", i,
               " timestamp ", p.timestamp, " s does not fit in 64-bit nanoseconds");
    // Whole seconds and the fraction apart: t * 1e9 would round the nanoseconds away.
    const double s = std::floor(p.timestamp);
    const std::int64_t ns = static_cast<std::int64_t>(s) * 1000000000 +
                            static_cast<std::int64_t>(std::llround((p.timestamp - s) * 1e9));
    out += std::to_string(ns);
    const Eigen::Quaterniond q(p.T_world_cam.linear());
    const Eigen::Vector3d t = p.T_world_cam.translation();
    for (const double v : {t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z()}) {
      out += ',';
      detail::append_double(out, v);
    }
    out += '\n';
  }
  return out;
}

inline std::string format_trajectory(const Trajectory& traj, TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kKitti:
      return format_kitti_trajectory(traj);
    case TrajectoryFormat::kEuroc:
      return format_euroc_trajectory(traj);
    case TrajectoryFormat::kTum:
      break;
  }
  return format_tum_trajectory(traj);
}

inline void write_trajectory(const std::filesystem::path& path, const Trajectory& traj,
                             TrajectoryFormat format) {
  detail::write_file_atomically(path, format_trajectory(traj, format), "ds3d::write_trajectory");
}

}  // namespace ds3d
