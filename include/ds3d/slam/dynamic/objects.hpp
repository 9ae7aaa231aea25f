// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The interfaces of the dynamic stages: frames in, objects out, and the sources and maskers.
#pragma once
/// @file objects.hpp
/// @brief What the SLAM front-end's dynamic stages exchange (ds3d::slam; OpenCV): FrameInput,
/// DynamicObjects (with its Segmentation), the DynamicObjectSource and DynamicFeatureMasker
/// interfaces, and their `none` implementations NoDynamicObjects and NoDynamicMasker.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/slam/orb_features.hpp"

namespace ds3d::slam {

/// One RGB-D frame as given to the stages (a view: the images are shared, not copied).
struct FrameInput {
  std::size_t index = 0;  ///< position in the input sequence (0-based)
  double timestamp = 0;   ///< [s], non-decreasing along the sequence
  cv::Mat rgb;            ///< CV_8UC3 BGR (or CV_8UC1 grey), camera.width × camera.height
  cv::Mat depth;          ///< CV_16UC1, camera.depth_scale units per metre, 0 = none; may be empty
  /// Optional: the ORB corners SlamFrontend::extract found in `rgb`, recorded when the source
  /// asks for them (DynamicObjectSource::uses_orb_corners) and dropped after detection. A source
  /// with its own OrbExtractor takes its features from them when the pyramids agree
  /// (OrbExtractor::extract_from): the same features, less work.
  std::shared_ptr<const OrbCorners> orb_corners;
};

/// A point segmentation that comes with some 3-D boxes (e.g. HtxSource's part head,
/// HtxSourceParams::segment), all in the camera frame [m]. The masker keeps a keypoint that a
/// flagged box made dynamic only when its 3-D point lies within foreground_radius of a
/// foreground point and, when background points are given, its nearest foreground point is no
/// farther than its nearest background point (nearest-neighbour label transfer: a seat under a
/// seated person's thighs is then not confirmed by the thigh points next to it); a keypoint on
/// segment_plane (within DynamicFilterParams::support_margin plus 3σ of its depth noise along
/// the normal, the rule of DynamicObjects::support_plane) counts as off the segment, since the
/// source removed that plane before segmenting and gives it no label. segment_plane takes no
/// part in the filter's gating. With segment_outside_boxes, outside every unsegmented box's
/// image rectangle each keypoint is decided by the segmentation as inside a segmented box's
/// rectangle, and a keypoint the filter kept static becomes dynamic when it passes the test
/// even where no box gated it (a body part outside a box that is too small, misplaced or
/// missed); used only in frames with at least one segmented box. Non-finite rows are ignored.
/// See HdbscanMasker.
struct Segmentation {
  Points3f foreground_points;  ///< points segmented as on the objects [m, camera frame]
  Points3f background_points;  ///< points segmented as off the objects [m], or empty
  /// One per DynamicObjects::boxes_3d entry, or empty (= none); non-zero = confirm it here.
  std::vector<std::uint8_t> boxes_3d_segmented;
  /// Plane (n, d), n·p + d = 0 (n need not be unit), removed before segmenting, or none.
  std::optional<Eigen::Vector4f> segment_plane;
  bool segment_outside_boxes = false;  ///< the segmentation covers the whole frame
  /// Largest keypoint-to-foreground-point distance [m] to count as on the segment, > 0.
  float foreground_radius = 0.2F;
};

/// The camera's motion as a source measured it: from the frame with timestamp
/// `reference_timestamp` (an earlier FrameInput::timestamp [s]) to this frame.
struct EgoMotion {
  double reference_timestamp = 0;  ///< [s], the earlier frame's FrameInput::timestamp
  /// Rigid motion taking a point from the reference camera frame to this camera frame [m].
  Eigen::Isometry3d T_cur_ref = Eigen::Isometry3d::Identity();
};

/// What a dynamic-object source found in one frame. All members are optional (empty = nothing).
struct DynamicObjects {
  std::vector<cv::Rect2f> boxes_2d;  ///< image boxes of moving objects [px, raw image]
  std::vector<float> scores;         ///< one confidence per 2-D box in [0, 1], or empty
  std::vector<Eigen::Matrix<float, 8, 3>> boxes_3d;  ///< corners of 3-D boxes, camera frame [m]
  cv::Mat pixel_mask;  ///< CV_8UC1 image-sized mask, non-zero = dynamic; or empty
  /// Metric uncertainty [m] of each 3-D box, one per boxes_3d entry, or empty (= all infinite).
  /// With a finite value the masker gates keypoints by the oriented box grown by it (3-D
  /// containment); infinite (or a box whose corners are not a cuboid): by the box's image
  /// rectangle and depth range only, as for sources that give loose evidence boxes.
  std::vector<float> boxes_3d_margin;
  /// The supporting plane (floor) in the camera frame, (n, d) with n·p + d = 0, when the source
  /// found one; the masker keeps keypoints on it static (dynamic_filter.hpp).
  std::optional<Eigen::Vector4f> support_plane;
  /// The segmentation that confirms the keypoints of the flagged 3-D boxes (empty = none).
  Segmentation segmentation;
  /// The camera's motion, from a source that estimates it on the static scene (the geometric
  /// source, when it trusted its pose), or none. FrontendConfig::source_motion_gate uses it.
  std::optional<EgoMotion> ego_motion;
};

/// What DynamicObjectSource::prepare computed for one frame; each source derives its own.
struct PreparedDetection {
  virtual ~PreparedDetection() = default;
};

/// Stage "dynamic-object source": finds moving objects in a frame (runs beside feature
/// extraction, as 3DS-SLAM's detection thread). detect() is called once per frame, in frame
/// order, from one thread at a time, so implementations may keep state across frames.
///
/// A source may split its work: prepare() does the part that needs no earlier frame (for HtxSource
/// the depth preprocessing and the network), detect_prepared() the rest. The threaded pipeline
/// then runs prepare() of frame t+1 on its own thread while detect_prepared() of frame t runs;
/// the objects are the same as detect()'s.
class DynamicObjectSource {
 public:
  virtual ~DynamicObjectSource() = default;
  /// Objects in `frame`. Must not throw for a valid frame; "nothing found" = empty result.
  virtual DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) = 0;
  /// The frame-independent part of detect(frame, camera), or nullptr (the default: detect does
  /// all). Called in frame order from one thread, concurrently with detect_prepared() of earlier
  /// frames, so it must not touch the state detect() keeps. Must not throw for a valid frame.
  [[nodiscard]] virtual std::shared_ptr<const PreparedDetection> prepare(
      const FrameInput& /*frame*/, const PinholeCamera& /*camera*/) const {
    return nullptr;
  }
  /// detect(frame, camera), reusing what prepare(frame, camera) returned for this same frame
  /// (nullptr or another source's result: as detect()). Same result as detect().
  virtual DynamicObjects detect_prepared(const FrameInput& frame, const PinholeCamera& camera,
                                         const PreparedDetection* /*prepared*/) {
    return detect(frame, camera);
  }
  /// True when detect() reads FrameInput::orb_corners (default false): SlamFrontend::extract
  /// records them only then.
  [[nodiscard]] virtual bool uses_orb_corners() const { return false; }
  /// Short name for logs and stats (e.g. "none", "htx").
  [[nodiscard]] virtual std::string name() const = 0;
};

/// Stage "dynamic filter": decides which keypoints lie on moving objects. Called once per frame,
/// in frame order, from one thread at a time.
class DynamicFeatureMasker {
 public:
  virtual ~DynamicFeatureMasker() = default;
  /// One byte per keypoint of `features` (same order): non-zero = dynamic, dropped before tracking.
  virtual std::vector<std::uint8_t> mask(const FrameInput& frame, const PinholeCamera& camera,
                                         const OrbFeatures& features,
                                         const DynamicObjects& objects) = 0;
  /// Short name for logs and stats (e.g. "none", "hdbscan").
  [[nodiscard]] virtual std::string name() const = 0;
};

/// The `none` source: finds nothing.
class NoDynamicObjects final : public DynamicObjectSource {
 public:
  DynamicObjects detect(const FrameInput&, const PinholeCamera&) override { return {}; }
  [[nodiscard]] std::string name() const override { return "none"; }
};

/// The `none` filter: keeps every keypoint.
class NoDynamicMasker final : public DynamicFeatureMasker {
 public:
  std::vector<std::uint8_t> mask(const FrameInput&, const PinholeCamera&,
                                 const OrbFeatures& features, const DynamicObjects&) override {
    return std::vector<std::uint8_t>(features.size(), 0);
  }
  [[nodiscard]] std::string name() const override { return "none"; }
};

}  // namespace ds3d::slam
