// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-slam's record of the dynamic stages per frame: boxes for --viz, masks for --dynamic-out.
#pragma once

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/slam/dynamic/hdbscan_masker.hpp"
#include "ds3d/slam/dynamic/objects.hpp"
#include "ds3d/slam/slam_frontend.hpp"

namespace ds3d_slam_tool {

/// What the dynamic stages flagged in one frame.
struct DynamicRecord {
  std::vector<ds3d::ImageBox> boxes;  ///< the filter's boxes as used (grown, clipped, carried)
  cv::Mat mask;                       ///< CV_8UC1 image-sized, 255 = dynamic (see dynamic_mask)
};

/// The region the dynamic stages flagged in a frame as a CV_8UC1 `width` x `height` image,
/// 255 = dynamic: every pixel that a point of the image rectangle of a box the filter processed
/// rounds to (columns lround(x_min) .. lround(x_max), rows likewise: the pixels a keypoint in
/// the box is read at) and every non-zero pixel of the source's pixel mask (when it has the
/// image's size, as the masker requires); 0 elsewhere.
[[nodiscard]] cv::Mat dynamic_mask(const std::vector<ds3d::ImageBox>& boxes,
                                   const cv::Mat& pixel_mask, int width, int height);

/// The HDBSCAN masker, remembering each frame's boxes (for --viz) and dynamic mask (for
/// --dynamic-out). The masker runs in the filter stage's thread, the writing on the caller's.
class RecordingMasker final : public ds3d::slam::DynamicFeatureMasker {
 public:
  explicit RecordingMasker(const ds3d::DynamicFilterParams& params) : inner_(params) {}
  std::vector<std::uint8_t> mask(const ds3d::slam::FrameInput& frame,
                                 const ds3d::PinholeCamera& camera,
                                 const ds3d::slam::OrbFeatures& features,
                                 const ds3d::slam::DynamicObjects& objects) override;
  [[nodiscard]] std::string name() const override { return inner_.name(); }
  /// Which records to keep (set before the first frame).
  void set_record(bool boxes, bool mask) {
    record_boxes_ = boxes;
    record_mask_ = mask;
  }
  /// The record of frame `index` (empty when none was kept), removed from the store.
  DynamicRecord take(std::size_t index);

 private:
  ds3d::slam::HdbscanMasker inner_;
  bool record_boxes_ = false;
  bool record_mask_ = false;
  std::mutex mutex_;
  std::map<std::size_t, DynamicRecord> records_;
};

/// "unmatched", "tracked", "dynamic" or "depth_edge".
[[nodiscard]] const char* status_name(ds3d::slam::KeypointStatus s) noexcept;

/// --dynamic-out DIR: DIR/<rgb file stem>.png per frame (the dynamic mask, written to a
/// temporary name and renamed) and DIR/keypoints.jsonl (one line per frame, flushed after each
/// frame), so that a run stopped early leaves complete files for the frames done.
class DynamicOutWriter {
 public:
  /// Creates (truncates) DIR/keypoints.jsonl. @throws ds3d::IoError naming it.
  DynamicOutWriter(std::filesystem::path dir, const ds3d::RgbdDataset& dataset);
  /// Writes frame r's mask (`mask`, or an all-zero image of the camera size when empty) and its
  /// keypoint line. @throws ds3d::IoError naming the file.
  void write(const ds3d::slam::TrackResult& r, const cv::Mat& mask);

 private:
  std::filesystem::path dir_;
  const ds3d::RgbdDataset& dataset_;
  std::ofstream jsonl_;
};

}  // namespace ds3d_slam_tool
