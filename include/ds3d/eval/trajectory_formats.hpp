// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file trajectory_formats.hpp
/// @brief Trajectories in the KITTI odometry and EuRoC MAV formats beside TUM (trajectory.hpp):
/// reading, writing and telling them apart.
///
/// - **TUM**: `timestamp tx ty tz qx qy qz qw` per line (trajectory.hpp).
/// - **KITTI** (Geiger et al., KITTI odometry devkit): 12 numbers per line, the 3x4 row-major
///   matrix [R | t] of the camera-to-world pose, no timestamps. Timestamps are then the line
///   index (0, 1, 2, ... seconds) or come from a separate list (KITTI's `times.txt`: one stamp
///   per line, see parse_timestamp_list()), one per pose line.
/// - **EuRoC** (Burri et al., "The EuRoC micro aerial vehicle datasets", IJRR 2016): CSV with
///   the header `#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],
///   q_RS_y [],q_RS_z []`: the timestamp in integer nanoseconds, the position, then the
///   quaternion **w first**. Columns after the eighth (the velocity and IMU biases of EuRoC's
///   ground-truth `data.csv`) are accepted and ignored.
///
/// Every reader returns what parse_tum_trajectory() returns: sorted by timestamp, a repeated
/// timestamp keeping its later line, lines with a NaN/inf value skipped and counted. Lines are
/// split as TUM lines are (',' and TAB separate like ' ', lines starting with '#' are skipped).

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "ds3d/eval/trajectory.hpp"

namespace ds3d {

/// A trajectory file format.
enum class TrajectoryFormat : std::uint8_t {
  kTum,    ///< `timestamp tx ty tz qx qy qz qw`
  kKitti,  ///< 12 numbers: 3x4 row-major [R | t], no timestamp
  kEuroc,  ///< CSV `timestamp [ns], px, py, pz, qw, qx, qy, qz[, ...]`
};

/// "tum", "kitti" or "euroc".
[[nodiscard]] const char* to_string(TrajectoryFormat f) noexcept;

/// Parses "tum", "kitti" or "euroc". @throws ds3d::InvalidArgument listing the valid names.
[[nodiscard]] TrajectoryFormat parse_trajectory_format(std::string_view name);

/// The format of a trajectory file from its name and content: `.csv` (any case) is EuRoC; else
/// a line naming the column `p_RS_R_x` (EuRoC's header) is EuRoC; else the first data line
/// decides: 12 values is KITTI, values separated by ',' with an integer first value (a time in
/// ns) is EuRoC, anything else is TUM (so an empty file is TUM).
/// @param path the file's name (only its extension is looked at)
/// @param text the file's content
[[nodiscard]] TrajectoryFormat detect_trajectory_format(const std::filesystem::path& path,
                                                        std::string_view text);

/// Parses KITTI odometry poses (see the file comment).
/// @param text       whole file content
/// @param timestamps one stamp [s] per pose line (KITTI's times.txt), or nullptr: the line index
/// @param source     name used in error messages (file name)
/// @throws ds3d::IoError naming source and line for a line without exactly 12 numbers, a token
///   that is not a number, or a rotation part that is not a rotation (max |RᵀR − I| > 1e-3 or
///   det R <= 0); naming source for a timestamp count other than the number of pose lines.
/// @note Rotations are re-orthonormalised (through a normalised quaternion), as TUM's are.
[[nodiscard]] TumReadResult parse_kitti_trajectory(std::string_view text,
                                                   const std::vector<double>* timestamps = nullptr,
                                                   std::string_view source = "<text>");

/// Parses EuRoC CSV poses (see the file comment). An integer timestamp is read exactly as
/// nanoseconds; a decimal one as a number of nanoseconds.
/// @param text    whole file content
/// @param options zero-quaternion policy (as for TUM)
/// @param source  name used in error messages (file name)
/// @throws ds3d::IoError naming source and line for a line with fewer than 8 values or a value
///   that is not a number.
[[nodiscard]] TumReadResult parse_euroc_trajectory(std::string_view text,
                                                   const TumReadOptions& options = {},
                                                   std::string_view source = "<text>");

/// Parses a list of timestamps [s]: the first value of every line (KITTI's times.txt, or the
/// first column of a TUM list), '#' lines skipped.
/// @throws ds3d::IoError naming source and line for a value that is not a finite number.
[[nodiscard]] std::vector<double> parse_timestamp_list(std::string_view text,
                                                       std::string_view source = "<text>");

/// Options of read_trajectory().
struct TrajectoryReadOptions {
  std::optional<TrajectoryFormat> format = std::nullopt;  ///< none: detect_trajectory_format()
  bool keep_zero_quaternion = false;                      ///< see TumReadOptions (TUM and EuRoC)
  /// Stamps of KITTI files (one per pose line); none: the line index. Ignored for TUM, EuRoC.
  std::optional<std::vector<double>> kitti_timestamps = std::nullopt;
};

/// What read_trajectory() read: TumReadResult and the format it read.
struct TrajectoryReadResult : TumReadResult {
  TrajectoryFormat format = TrajectoryFormat::kTum;  ///< the format read
};

/// Reads a trajectory file in any of the three formats. A TUM file is read exactly as
/// read_tum_file() reads it.
/// @throws ds3d::IoError when the file cannot be read or is malformed (file and line named).
[[nodiscard]] TrajectoryReadResult read_trajectory(const std::filesystem::path& path,
                                                   const TrajectoryReadOptions& options = {});

/// Reads a timestamp list file (parse_timestamp_list()). @throws ds3d::IoError.
[[nodiscard]] std::vector<double> read_timestamp_list(const std::filesystem::path& path);

/// KITTI text: one line of 12 numbers per pose (timestamps are dropped), shortest round-trip
/// decimals. @throws ds3d::InvalidArgument for a non-finite pose (names the index).
[[nodiscard]] std::string format_kitti_trajectory(const Trajectory& traj);

/// EuRoC CSV text with its 8-column header; timestamps as integer nanoseconds (rounded; exact
/// for the stamps read from EuRoC up to the spacing of doubles, 0.24 µs at current Unix times).
/// @throws ds3d::InvalidArgument for a non-finite pose or a |timestamp| >= 9.2e9 s (names the
///   index).
[[nodiscard]] std::string format_euroc_trajectory(const Trajectory& traj);

/// The text of `traj` in `format` (format_tum_trajectory() for TUM).
/// @throws ds3d::InvalidArgument as the format's formatter.
[[nodiscard]] std::string format_trajectory(const Trajectory& traj, TrajectoryFormat format);

/// Writes `traj` in `format` atomically (temporary file + rename, as write_tum_trajectory()).
/// @throws ds3d::InvalidArgument for a non-finite pose; ds3d::IoError when writing fails.
void write_trajectory(const std::filesystem::path& path, const Trajectory& traj,
                      TrajectoryFormat format);

}  // namespace ds3d

#include "ds3d/detail/trajectory_formats_impl.hpp"
