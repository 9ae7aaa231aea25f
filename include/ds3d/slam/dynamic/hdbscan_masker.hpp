// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HdbscanMasker: the box-gated HDBSCAN filter on the ORB keypoints.
#pragma once
/// @file hdbscan_masker.hpp
/// @brief The `hdbscan` dynamic-feature masker, with the segmentation check of segmented boxes
/// (ds3d::slam; OpenCV).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "ds3d/camera.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/slam/dynamic/boxes.hpp"
#include "ds3d/slam/dynamic/objects.hpp"
#include "ds3d/slam/orb_features.hpp"

namespace ds3d::slam {

/// The `hdbscan` masker: DynamicFeatureFilter (box-gated HDBSCAN, 3DS-SLAM §III-C) on the ORB
/// keypoints, with boxes from DynamicObjects (2-D boxes, projected 3-D boxes); keypoints on a
/// non-zero pixel of DynamicObjects::pixel_mask are dynamic as well. Depth is read from the raw
/// depth image at the keypoint (so points beyond the ORB close/far threshold still get theirs),
/// falling back to the feature's depth when the frame has no depth image.
///
/// **Segmented boxes** (Segmentation::boxes_3d_segmented, e.g. HtxSource with segment): after
/// the filter, a dynamic keypoint that lies in no unsegmented box's image rectangle stays
/// dynamic only if its 3-D point (camera back-projection of its pixel and depth) lies within
/// Segmentation::foreground_radius of a foreground point and, when the source also gives
/// Segmentation::background_points, that foreground point is no farther than the nearest
/// background point (nearest-neighbour label transfer), and it does not lie on
/// Segmentation::segment_plane when one is given (within DynamicFilterParams::support_margin
/// plus 3σ of its depth noise along the normal: the floor the source removed before segmenting).
/// Conversely, a keypoint with depth that
/// the filter kept static although it passed the gates of a box (DynamicFilterResult::gated:
/// rectangle, depth range, support plane, solid) becomes dynamic when it lies in a segmented
/// box's rectangle, in no unsegmented one's, and passes that test (the filter's cluster choice
/// missed it: a desk in front took the foreground cluster, a seated person split in depth).
/// With Segmentation::segment_outside_boxes the whole image outside the unsegmented boxes'
/// rectangles counts as a segmented box's rectangle and the gate condition is dropped: every
/// keypoint there that passes the test is dynamic (a body part outside a too-small box).
/// A keypoint without depth inside a segmented box's rectangle, or made dynamic by the filter
/// outside every box's rectangle (a region carried from the previous frame), takes a depth from the
/// valid depths in the (2·kForegroundWindow + 1)² pixels around it (depth holes fringe object
/// silhouettes): their median or, when they split at a gap of kHoleDepthGap or more, the
/// median of the side whose colour (the mean of its pixels nearest to the keypoint) matches
/// the keypoint's own pixel in FrameInput::rgb best (median of all without a CV_8UC3 image of
/// the depth's size); it is dynamic exactly when that point passes the same test (no valid
/// depth there: static). So the segmentation decides inside the gated boxes: furniture in a
/// person's box, false boxes without foreground, floor at the feet and (with background
/// points) the seat under a seated person's thighs stay static (docs/dynamic.md).
class HdbscanMasker final : public DynamicFeatureMasker {
 public:
  /// @throws ds3d::InvalidArgument on bad params.
  explicit HdbscanMasker(const DynamicFilterParams& params = {});
  std::vector<std::uint8_t> mask(const FrameInput& frame, const PinholeCamera& camera,
                                 const OrbFeatures& features,
                                 const DynamicObjects& objects) override;
  [[nodiscard]] std::string name() const override { return "hdbscan"; }
  /// The filter's outcome for the last frame (boxes, clusters, fallback use), before the
  /// segmentation check and the pixel mask.
  [[nodiscard]] const DynamicFilterResult& last_result() const noexcept { return last_; }
  /// Half-size [px] of the depth window for keypoints without depth in segmented boxes.
  static constexpr int kForegroundWindow = 4;
  /// Depth gap [m] in that window taken for a silhouette (an object in front of what it hides):
  /// the hole then takes the depth of the side matching its colour.
  static constexpr double kHoleDepthGap = 0.1;
  /// Keypoints the segmentation check made static (last frame).
  [[nodiscard]] std::size_t last_vetoed() const noexcept { return vetoed_; }
  /// Keypoints the segmentation check made dynamic (last frame): gated keypoints with depth the
  /// filter kept static, and keypoints without depth.
  [[nodiscard]] std::size_t last_added() const noexcept { return added_; }

 private:
  void confirm_foreground(const FrameInput& frame, const PinholeCamera& camera,
                          const Keypoints3f& kp, const DynamicObjects& objects,
                          std::vector<std::uint8_t>& out);
  DynamicFeatureFilter filter_;
  DynamicFilterResult last_;
  std::size_t vetoed_ = 0;
  std::size_t added_ = 0;
};

}  // namespace ds3d::slam
