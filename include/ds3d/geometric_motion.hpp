// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file geometric_motion.hpp
/// @brief GeometricMotionSource: a dynamic-object source that needs no learned weights
/// (ds3d::slam; OpenCV). It finds moving objects from multi-view geometry alone.
///
/// Per frame (the source keeps its own short history of frames):
///  1. ORB features of the frame (its own extractor, so it runs beside the front-end's); matches
///     to a reference frame `reference_gap` frames back (mutual best Hamming matches);
///  2. robust pose: PnP-RANSAC (EPnP minimal sets, then iterative refinement on the inliers) of
///     the reference's 3-D points against the current pixels, excluding points inside objects
///     that are already known to move;
///  3. per matched keypoint, its reprojection residual (χ² test at 2 dof, σ scaled by the pyramid
///     level as in ORB-SLAM2) and its depth residual (3σ of the sensor noise σ(z) = k·z²,
///     Khoshelham & Elberink 2012, floored by min_depth_residual) flag moving keypoints;
///  4. depth-warp consistency: pixels of a grid of the current depth image are warped into the
///     reference frame; where the reference saw (in a small neighbourhood, to tolerate edges)
///     only surfaces farther than the warped point, the space the point occupies now was empty
///     then, so the point moved in (the converse case, now-hidden background, is ignored);
///  5. HDBSCAN on the flagged points in (u, v, z) (pixels scaled to metres at the median depth)
///     groups them into objects; clusters must be dense (median core distance within
///     dense_factor warp-grid steps at their depth: scattered mismatches are not objects); each
///     cluster becomes a 3-D box (camera-frame axis-aligned hull of its back-projected points,
///     grown by box_margin) held in the world frame;
///  6. a cluster becomes an object only when evidence repeats at the same place (overlapping
///     world boxes) in consecutive frames, or confirms a held object: a one-frame pose glitch
///     does not remove the static scene;
///  7. an object is reported for `hold_frames` frames after its last motion evidence, so that a
///     person who stops for a while after moving is still removed.
/// Objects are reported as DynamicObjects::boxes_3d (camera frame), so that the masker can gate
/// the keypoints by their depth range.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "ds3d/orb_features.hpp"
#include "ds3d/slam_frontend.hpp"

namespace ds3d::slam {

/// Parameters of GeometricMotionSource. Thresholds are statistical (χ², σ(z)) or metric.
struct GeometricMotionParams {
  int num_features = 800;           ///< ORB features of the source's own extractor, > 0
  int reference_gap = 4;            ///< frames between the current and the reference frame, >= 1
  int max_match_distance = 50;      ///< Hamming distance of accepted matches, in [1, 256]
  int ransac_iterations = 200;      ///< PnP-RANSAC iterations, >= 1
  double chi2_2dof = 5.991;         ///< χ²(2 dof, 95%) for the pose inlier test, > 0
  double moving_chi2_factor = 9.0;  ///< a keypoint moves if its χ² exceeds this × chi2_2dof, >= 1
  float depth_noise = 1.5e-3F;      ///< σ(z) = depth_noise·z² [1/m], >= 0
  float min_depth_residual = 0.10F;  ///< floor of the depth residual threshold [m], > 0
  int warp_stride = 6;               ///< grid step of the depth-warp check [px], >= 1
  int warp_window = 3;               ///< half-size of the reference min-depth window [px], >= 0
  double max_depth = 6.0;            ///< depths beyond this are ignored [m], > 0
  int min_cluster_size = 15;         ///< HDBSCAN min_cluster_size for objects, >= 2
  int min_samples = 5;               ///< HDBSCAN min_samples, >= 1
  double dense_factor = 3.0;  ///< clusters need median core distance <= this × grid step, > 0
  double max_object_size =
      2.5;                    ///< clusters larger than this in x, y or z are not objects [m], > 0
  float box_margin = 0.2F;    ///< object boxes grow by this in x, y and z [m], >= 0
  int hold_frames = 90;       ///< frames an object is kept after its last motion, >= 0
  int min_pose_inliers = 20;  ///< fewer PnP inliers: no motion test this frame, >= 6
  void validate() const;      ///< throws ds3d::InvalidArgument naming the bad field
};

/// Statistics of the last detect() call.
struct GeometricMotionStats {
  bool pose_ok = false;          ///< a reference was available and the pose had enough inliers
  int num_matches = 0;           ///< descriptor matches with the reference
  int num_pose_inliers = 0;      ///< PnP-RANSAC inliers
  int num_moving_keypoints = 0;  ///< matched keypoints flagged by residuals
  int num_moving_pixels = 0;     ///< grid pixels flagged by the depth-warp check
  int num_new_objects = 0;       ///< clusters found this frame
  int num_objects = 0;           ///< objects reported (new + held)
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< the source's own pose
};

/// The `geometric` dynamic-object source (see the file comment for the method).
/// @note Deterministic for a given frame sequence. Keeps state across frames: call detect() in
///       frame order (the SLAM pipeline does); not thread-safe.
class GeometricMotionSource final : public DynamicObjectSource {
 public:
  /// @throws ds3d::InvalidArgument on bad params.
  explicit GeometricMotionSource(const GeometricMotionParams& params = {});
  /// Moving objects of `frame` as 3-D boxes (camera frame). Frames without depth give nothing.
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  [[nodiscard]] std::string name() const override { return "geometric"; }
  /// Counters of the last detect() call (matches, moving keypoints, warp pixels, objects).
  [[nodiscard]] const GeometricMotionStats& last_stats() const noexcept { return stats_; }
  /// The parameters as validated by the constructor.
  [[nodiscard]] const GeometricMotionParams& params() const noexcept { return params_; }

 private:
  struct Past {
    OrbFeatures features;
    cv::Mat min_depth;  // CV_16UC1, windowed minimum of the depth (0 → 65535)
    cv::Mat depth;
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  };
  struct Held {
    Eigen::Matrix<double, 8, 3> corners_world;
    Eigen::Vector3d centre_world;
    std::size_t last_seen = 0;
  };
  GeometricMotionParams params_;
  OrbExtractor extractor_;
  std::deque<Past> history_;
  std::vector<Held> held_;
  std::vector<Held> candidates_;  // clusters of the previous frame, awaiting confirmation
  std::size_t frame_count_ = 0;
  GeometricMotionStats stats_;
};

}  // namespace ds3d::slam
