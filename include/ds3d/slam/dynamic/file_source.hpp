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
#include "ds3d/dynamic/dynamic_filter.hpp"
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
  /// Frames a 3-D box is carried after the file last reported it, >= 0 (0 = off), default 10
  /// (key `file.hold_frames`). A detector misses people in runs of frames; a held box keeps a
  /// person it lost out of the map meanwhile. A held box is reported again unless a box of the
  /// frame continues it (its centre within the held box's largest half size) or fewer than
  /// hold_min_points depth points (voxel centroids off the floor, preprocess defaults) lie in it,
  /// grown by hold_margin per side; it moves with their centroid (two mean-shift steps), so it
  /// follows the person and the camera. 2-D boxes are not held (they carry no depth to follow);
  /// a frame without a detections line within max_dt reports nothing, held boxes included.
  int hold_frames = 10;
  int hold_min_points = 5;  ///< depth points that keep a carried box, >= 1
  /// Growth per side [m] of a held box when its points are gathered, finite, >= 0: what a person
  /// walks in one frame at 30 Hz and a few km/h, plus the box's own error.
  float hold_margin = 0.15F;
  /// Longest time [s] a box is carried after the file reported it, finite, >= 0: with frames far
  /// apart the camera-frame box no longer fits.
  double hold_seconds = 0.5;
  void validate() const;  ///< throws ds3d::InvalidArgument naming the bad field
};

/// The `file:PATH` source: boxes per timestamp from a detections file (detections.hpp), so that
/// any external detector (2-D or 3-D, run offline) drives ds3d.
/// @note The file is read once in the constructor; detect() is O(log F + boxes), plus
///   O(pixels) for the floor (report_floor) and, with held boxes, O(points × held boxes).
class FileSource final : public DynamicObjectSource {
 public:
  /// @throws ds3d::IoError when the file cannot be read or is malformed;
  ///   ds3d::InvalidArgument on bad params.
  explicit FileSource(const std::filesystem::path& path, FileSourceParams params = {});
  /// Builds the source from already parsed detections. @throws ds3d::InvalidArgument on bad params.
  explicit FileSource(DetectionsFile detections, FileSourceParams params = {});
  /// 2-D boxes (with scores) and 3-D corner boxes of the frame nearest in time within max_dt,
  /// the 3-D boxes still held from earlier frames (hold_frames), and with report_floor the
  /// frame's floor when it has a box. Call it in time order: the held boxes are state.
  /// @throws ds3d::InvalidArgument when the camera is invalid (report_floor only).
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  [[nodiscard]] std::string name() const override { return "file"; }
  /// Frames whose timestamp matched a detections line so far, and frames that did not.
  [[nodiscard]] std::size_t num_matched() const noexcept { return matched_; }
  /// Frames for which no detections line was within max_dt (see num_matched()).
  [[nodiscard]] std::size_t num_unmatched() const noexcept { return unmatched_; }
  /// Held boxes reported so far, over all frames (hold_frames).
  [[nodiscard]] std::size_t num_carried() const noexcept { return carried_; }

 private:
  // A 3-D box of an earlier frame (hold_frames): its corners and solid, moved with the centroid
  // of the depth points in it [m, camera frame], which lies `offset` from the solid's centre.
  struct HeldBox {
    Eigen::Matrix<float, 8, 3> corners;
    SolidBox solid;
    Eigen::Vector3f offset;
    double timestamp = 0;  // [s] of the last report in the file
    int age = 0;           // frames carried since then
  };
  void hold(const FrameInput& frame, const Points3f* points, DynamicObjects& out);
  std::vector<HeldBox> held_;
  std::size_t carried_ = 0;
  DetectionsFile file_;
  FileSourceParams params_;
  PixelRayCache rays_;  // undistortion table of the camera (distorted cameras only)
  std::size_t matched_ = 0;
  std::size_t unmatched_ = 0;
};

}  // namespace ds3d::slam
