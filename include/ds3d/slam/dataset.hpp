// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file dataset.hpp
/// @brief TUM RGB-D and Bonn RGB-D Dynamic folders, read as they come, frame by frame
/// (compiled into ds3d::slam; needs OpenCV imgcodecs).
///
/// A folder holds `rgb.txt` and `depth.txt` (`timestamp filename` lines), the images they list
/// (.png or .jpg, paths relative to the folder), optionally `groundtruth.txt` (TUM trajectory)
/// and `camera.txt` (`key value` lines: fx fy cx cy k1 k2 p1 p2 k3 depth_scale, optional width
/// height). RGB and depth are associated like the TUM tool associate.py (Sturm et al. 2012):
/// greedy one-to-one on |t_rgb - (t_depth + offset)| < max_difference.

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/detail/abi_guard.hpp"

namespace ds3d {

/// One associated RGB-D frame, images loaded.
struct RgbdFrame {
  std::size_t index = 0;       ///< position in the associated sequence
  double timestamp = 0;        ///< rgb timestamp [s]
  double depth_timestamp = 0;  ///< associated depth timestamp [s]
  cv::Mat rgb;                 ///< CV_8UC3, BGR (as cv::imread)
  cv::Mat depth;               ///< CV_16UC1 raw units (camera.depth_scale per metre), 0 = invalid
};

/// Built-in intrinsics (640 x 480, depth_scale 5000), from the TUM RGB-D "file formats / camera
/// calibration" page and the Bonn RGB-D Dynamic dataset:
/// "tum1" (freiburg1, with distortion), "tum2" (freiburg2, with distortion), "tum3" (freiburg3,
/// no distortion), "tum_ros" (ROS default 525, 525, 319.5, 239.5), "bonn" (Asus Xtion).
/// @throws ds3d::InvalidArgument for any other name (the message lists the valid ones).
[[nodiscard]] PinholeCamera camera_preset(std::string_view name);

/// Preset for a dataset folder without camera.txt, from the standard folder names of the TUM
/// RGB-D benchmark (`rgbd_dataset_freiburg1_*` -> "tum1", `rgbd_dataset_freiburg2_*` -> "tum2",
/// `rgbd_dataset_freiburg3_*` -> "tum3") and the Bonn RGB-D Dynamic dataset (`rgbd_bonn_*` ->
/// "bonn"); std::nullopt for any other name. Only the last component of `dir` is looked at.
[[nodiscard]] std::optional<std::string> camera_preset_for_folder(const std::filesystem::path& dir);

/// Parses camera.txt content: one `key value` per line, '#' comments; keys fx fy cx cy (required),
/// k1 k2 p1 p2 k3 (default 0), depth_scale (default 5000), width height (default 640 480).
/// @param text   the file's content
/// @param source name used in error messages
/// @throws ds3d::IoError naming source and line for an unknown or repeated key, a value that is
///         not a number, a missing required key or an invalid camera; naming source, key and
///         value for an implausible one: fx, fy outside [1, 1e5] px, cx outside [-width,
///         2 width], cy outside [-height, 2 height], depth_scale outside [1e-6, 1e9].
[[nodiscard]] PinholeCamera parse_camera_text(std::string_view text,
                                              std::string_view source = "<text>");

/// Reads a camera.txt file (see parse_camera_text()). @throws ds3d::IoError.
[[nodiscard]] PinholeCamera read_camera_file(const std::filesystem::path& path);

/// Options of RgbdDataset::open().
struct DatasetOptions {
  double max_difference = 0.02;  ///< rgb-depth association window [s], >= 0 (associate.py)
  double offset = 0.0;           ///< added to depth stamps [s]
  std::optional<PinholeCamera> camera = std::nullopt;  ///< overrides camera.txt and the default
};

/// What RgbdDataset::open() noticed in the lists without rejecting them (a tool warns about
/// each non-zero count; the library prints nothing).
struct DatasetDiagnostics {
  std::size_t rgb_duplicates = 0;    ///< rgb.txt lines replaced by a later line, same stamp
  double first_rgb_duplicate = 0;    ///< stamp of the first of them [s]
  std::size_t depth_duplicates = 0;  ///< depth.txt lines replaced by a later line, same stamp
  double first_depth_duplicate = 0;  ///< stamp of the first of them [s]
  std::size_t unassociated_rgb = 0;  ///< rgb stamps with no depth stamp within max_difference
  std::size_t large_gaps = 0;        ///< consecutive associated frames > gap_threshold apart
  double first_gap_start = 0;        ///< rgb stamp of the frame before the first such gap [s]
  double first_gap_seconds = 0;      ///< length of that gap [s]
  double gap_threshold = 0;          ///< max(1 s, 10 x the median frame interval) [s]
};

/// One associated rgb/depth pair (file names relative to the dataset folder).
struct RgbdEntry {
  double timestamp = 0;        ///< rgb stamp [s]
  std::string rgb_file;        ///< as listed in rgb.txt
  double depth_timestamp = 0;  ///< depth stamp [s]
  std::string depth_file;      ///< as listed in depth.txt
};

/// A TUM-layout RGB-D sequence. Opening reads only the lists; frame() loads images on demand.
/// @note const member functions are safe to call concurrently (frame() only reads files).
class RgbdDataset {
 public:
  /// Opens a folder: reads rgb.txt and depth.txt and associates them.
  /// @param dir folder in TUM layout
  /// @param options association window/offset and camera override
  /// @throws ds3d::IoError for a missing folder or list, a timestamp that is not a number, or a
  ///         bad camera.txt; ds3d::InvalidArgument for bad options.
  /// @note O(n log n) in the list lengths; no image is read.
  static RgbdDataset open(const std::filesystem::path& dir, const DatasetOptions& options = {});

  /// Number of associated rgb/depth pairs.
  [[nodiscard]] std::size_t size() const;

  /// Loads frame i (rgb as BGR CV_8UC3, depth as raw CV_16UC1).
  /// @throws ds3d::InvalidArgument for i >= size(); ds3d::IoError for an unreadable image, a
  ///         truncated JPEG (no end-of-image marker; libjpeg would only warn and return a
  ///         partly grey image), a depth image that is not 16-bit single-channel, or rgb/depth
  ///         of different sizes. Every message names the file.
  [[nodiscard]] RgbdFrame frame(std::size_t i) const;

  /// options.camera, else camera.txt in the folder, else the preset of a recognised folder name
  /// (camera_preset_for_folder(); one info line on stderr names it), else camera_preset("tum_ros")
  /// with a one-line warning on stderr.
  [[nodiscard]] const PinholeCamera& camera() const;

  /// The folder given to open().
  [[nodiscard]] const std::filesystem::path& directory() const;

  /// `groundtruth.txt` in the folder, when it exists.
  [[nodiscard]] std::optional<std::filesystem::path> groundtruth_path() const;

  /// The associated pairs, sorted by rgb stamp.
  [[nodiscard]] const std::vector<RgbdEntry>& entries() const;

  /// Duplicate stamps, unassociated rgb frames and large time gaps found by open().
  [[nodiscard]] const DatasetDiagnostics& diagnostics() const noexcept { return diagnostics_; }

 private:
  RgbdDataset() = default;
  std::filesystem::path dir_;
  PinholeCamera camera_;
  std::vector<RgbdEntry> entries_;
  DatasetDiagnostics diagnostics_;
};

}  // namespace ds3d
