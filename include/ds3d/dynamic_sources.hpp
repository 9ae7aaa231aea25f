// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file dynamic_sources.hpp
/// @brief Adapters that plug the dynamic-feature removal into the SLAM front-end's hooks
/// (ds3d::slam; OpenCV): FileSource (boxes from a JSON-lines detections file), HdbscanMasker
/// (DynamicFeatureFilter on the ORB keypoints), and conversions between DynamicObjects and
/// ImageBox lists. GeometricMotionSource (no learned weights) is in geometric_motion.hpp.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "ds3d/detections.hpp"
#include "ds3d/dynamic_filter.hpp"
#include "ds3d/slam_frontend.hpp"

namespace ds3d::slam {

/// Options of FileSource.
struct FileSourceParams {
  double max_dt = 0.02;    ///< largest frame ↔ detection timestamp difference [s], >= 0
  float min_score = 0.0F;  ///< detections below this score are dropped, in [0, 1]
  std::vector<std::string> classes{};  ///< classes treated as dynamic; empty = every class
  void validate() const;               ///< throws ds3d::InvalidArgument naming the bad field
};

/// The `file:PATH` source: boxes per timestamp from a detections file (detections.hpp), so that
/// any external detector (2-D or 3-D, run offline) drives ds3d.
/// @note The file is read once in the constructor; detect() is O(log F + boxes).
class FileSource final : public DynamicObjectSource {
 public:
  /// @throws ds3d::IoError when the file cannot be read or is malformed;
  ///   ds3d::InvalidArgument on bad params.
  explicit FileSource(const std::filesystem::path& path, FileSourceParams params = {});
  /// Builds the source from already parsed detections. @throws ds3d::InvalidArgument on bad params.
  explicit FileSource(DetectionsFile detections, FileSourceParams params = {});
  /// 2-D boxes (with scores) and 3-D corner boxes of the frame nearest in time within max_dt.
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  [[nodiscard]] std::string name() const override { return "file"; }
  /// Frames whose timestamp matched a detections line so far, and frames that did not.
  [[nodiscard]] std::size_t num_matched() const noexcept { return matched_; }
  /// Frames for which no detections line was within max_dt (see num_matched()).
  [[nodiscard]] std::size_t num_unmatched() const noexcept { return unmatched_; }

 private:
  DetectionsFile file_;
  FileSourceParams params_;
  std::size_t matched_ = 0;
  std::size_t unmatched_ = 0;
};

/// The `hdbscan` masker: DynamicFeatureFilter (box-gated HDBSCAN, 3DS-SLAM §III-C) on the ORB
/// keypoints, with boxes from DynamicObjects (2-D boxes, projected 3-D boxes); keypoints on a
/// non-zero pixel of DynamicObjects::pixel_mask are dynamic as well. Depth is read from the raw
/// depth image at the keypoint (so points beyond the ORB close/far threshold still get theirs),
/// falling back to the feature's depth when the frame has no depth image.
class HdbscanMasker final : public DynamicFeatureMasker {
 public:
  /// @throws ds3d::InvalidArgument on bad params.
  explicit HdbscanMasker(const DynamicFilterParams& params = {});
  std::vector<std::uint8_t> mask(const FrameInput& frame, const PinholeCamera& camera,
                                 const OrbFeatures& features,
                                 const DynamicObjects& objects) override;
  [[nodiscard]] std::string name() const override { return "hdbscan"; }
  /// The filter's outcome for the last frame (boxes, clusters, fallback use).
  [[nodiscard]] const DynamicFilterResult& last_result() const noexcept { return last_; }

 private:
  DynamicFeatureFilter filter_;
  DynamicFilterResult last_;
};

/// The image boxes of `objects`: its 2-D boxes (with their scores, 1 when absent) and its 3-D
/// boxes projected with `camera` (with their depth ranges); boxes wholly outside the image or
/// behind the camera are left out.
/// @throws ds3d::InvalidArgument when `scores` is neither empty nor one per 2-D box.
[[nodiscard]] std::vector<ImageBox> image_boxes(const DynamicObjects& objects,
                                                const PinholeCamera& camera);

/// Keypoints of `features` as (u, v, z) rows: raw pixel, and the depth of `depth` at the rounded
/// pixel (0 = none) when `depth` is a CV_16UC1 image of the camera size, else features.depth.
[[nodiscard]] Keypoints3f keypoint_array(const OrbFeatures& features, const cv::Mat& depth,
                                         const PinholeCamera& camera);

/// Builds the source named by a `--dynamic` option value: "none", "file:PATH" or "geometric"
/// (GeometricMotionSource with default parameters).
/// @throws ds3d::InvalidArgument for an unknown name; ds3d::IoError for an unreadable file.
[[nodiscard]] std::shared_ptr<DynamicObjectSource> make_dynamic_source(const std::string& spec);

}  // namespace ds3d::slam
