// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// FileSource: dynamic objects read from a detections file.
#pragma once
/// @file file_source.hpp
/// @brief The `file:PATH` dynamic-object source and its options (ds3d::slam; OpenCV).

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "ds3d/camera.hpp"
#include "ds3d/dynamic/detections.hpp"
#include "ds3d/preprocess/rgbd.hpp"
#include "ds3d/slam/dynamic/objects.hpp"

namespace ds3d::slam {

/// Options of FileSource.
struct FileSourceParams {
  double max_dt = 0.02;    ///< largest frame ↔ detection timestamp difference [s], >= 0
  float min_score = 0.0F;  ///< detections below this score are dropped, in [0, 1]
  std::vector<std::string> classes{};  ///< classes treated as dynamic; empty = every class
  /// Report the frame's floor as DynamicObjects::support_plane in frames with detections, so
  /// that the masker keeps the keypoints on it static in every box (key `file.report_floor`).
  /// A detection box carries no segmentation, and its rectangle, depth range and solid all hold
  /// the floor around a person's feet: in a crowd that floor is much of the static view left.
  /// The floor is preprocess's RANSAC ground search (PreprocessParams defaults: within 30° of
  /// camera −y, 2 cm band, at least 5 % of the voxel centroids) on the frame's depth image; a
  /// frame without a 16-bit depth image of the camera's size, or without such a plane, reports
  /// none. About 1–2 ms per frame.
  bool report_floor = true;
  void validate() const;  ///< throws ds3d::InvalidArgument naming the bad field
};

/// The `file:PATH` source: boxes per timestamp from a detections file (detections.hpp), so that
/// any external detector (2-D or 3-D, run offline) drives ds3d.
/// @note The file is read once in the constructor; detect() is O(log F + boxes), plus
///   O(pixels) for the floor (report_floor).
class FileSource final : public DynamicObjectSource {
 public:
  /// @throws ds3d::IoError when the file cannot be read or is malformed;
  ///   ds3d::InvalidArgument on bad params.
  explicit FileSource(const std::filesystem::path& path, FileSourceParams params = {});
  /// Builds the source from already parsed detections. @throws ds3d::InvalidArgument on bad params.
  explicit FileSource(DetectionsFile detections, FileSourceParams params = {});
  /// 2-D boxes (with scores) and 3-D corner boxes of the frame nearest in time within max_dt,
  /// and with report_floor the frame's floor when it has a box.
  /// @throws ds3d::InvalidArgument when the camera is invalid (report_floor only).
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  [[nodiscard]] std::string name() const override { return "file"; }
  /// Frames whose timestamp matched a detections line so far, and frames that did not.
  [[nodiscard]] std::size_t num_matched() const noexcept { return matched_; }
  /// Frames for which no detections line was within max_dt (see num_matched()).
  [[nodiscard]] std::size_t num_unmatched() const noexcept { return unmatched_; }

 private:
  DetectionsFile file_;
  FileSourceParams params_;
  PixelRayCache rays_;  // undistortion table of the camera (distorted cameras only)
  std::size_t matched_ = 0;
  std::size_t unmatched_ = 0;
};

}  // namespace ds3d::slam
