// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file geometric_motion.hpp
/// @brief GeometricMotionSource: a dynamic-object source that needs no learned weights
/// (ds3d::slam; OpenCV). It finds moving objects from multi-view geometry alone.
///
/// Per frame (the source keeps its own short history of frames):
///  1. ORB features of the frame (its own extractor; picked from FrameInput::orb_corners, the
///     front-end's corners, when the pyramids agree: OrbExtractor::extract_from), mutually
///     matched (with Lowe's ratio test) to a reference frame `reference_gap` frames back (the
///     oldest one with a trusted pose);
///  2. robust pose: PnP-RANSAC (EPnP minimal sets, then Levenberg-Marquardt on the inliers) of
///     the reference's 3-D points against the current pixels, leaving out points inside objects
///     already known to move, refined with the constant-velocity prediction as a prior on the
///     camera centre; where that pose breaks the prediction, a second one from the matches the
///     prediction explains, refined the same way, may replace it (`max_acceleration`), and where
///     no second one exists and the first is a weak consensus, the prediction itself is the pose
///     (`hold_prediction_inliers`). The pose is *trusted* only with at least
///     `min_pose_inliers` inliers forming at least `min_inlier_ratio` of the matches; otherwise
///     nothing new is flagged (an uncertain pose flags nothing rather than everything);
///  3. per matched keypoint with depth on both sides, a 3-dof χ² test of its residual
///     (Δu, Δv, Δz) against the static prediction, with a per-keypoint covariance: pixel noise
///     σ_px·(pyramid scale) in both views, where σ_px is estimated per frame from the median
///     residual of all matches (so blur and rolling shutter raise it), plus depth noise
///     σ(z) = depth_noise·z² (Khoshelham & Elberink 2012) inflated by the depth spread in a small
///     window, propagated through the projection (Jacobian of (u, v, z) with respect to the
///     reference depth). A keypoint moves when χ² > `moving_chi2` (χ²₃ at 99.9 %). Keypoints
///     on a depth discontinuity in either view (window spread above max(min_depth_residual,
///     3√2·σ(z))) are not tested: silhouette corners and T-junctions are not fixed 3-D points;
///  4. HDBSCAN groups the moving keypoints in (u, v, z) (pixels scaled to metres at the median
///     depth). A cluster becomes an object candidate only if it is compact (≤ `max_object_size`)
///     and has support: at least `min_support` of all tested keypoints inside its image rectangle
///     and depth range are moving. Scattered false alarms on static structure fail this test;
///  5. dense depth-warp evidence (a detector of its own, for textureless or repeatedly textured
///     movers whose descriptors cannot be matched): a grid of current depth pixels is warped
///     with the trusted pose into the reference; a pixel lying in front of every surface the
///     reference saw in a window, by more than a χ²₁ test of the depth noise of both views
///     (σ(z) = depth_noise·z², floored at min_depth_residual), was empty space then: something
///     moved in. Pixels on a depth edge or next to missing depth in either view, and pixels
///     behind the reference surface (occlusion, disocclusion), are never evidence. Flagged
///     pixels are grouped into depth-continuous connected components; components of at least
///     `min_warp_area` square metres that pass the support test become candidates too, and
///     overlapping keypoint and warp candidates are merged;
///  6. a candidate becomes an object only when it repeats at the same world place (overlapping
///     world boxes) in consecutive frames, or confirms a held object; in the first frame tested
///     with a trusted pose, which no earlier frame can confirm, at once (trust_first_candidates);
///  7. an object is reported for `hold_frames` frames after its last motion evidence, so that a
///     person who stops for a while after moving is still removed;
///  8. object segments (`segment_objects`): the evidence of an object covers only what moved
///     into empty space and its matched keypoints, often a band at a walker's leading edge.
///     Seeded by it (and by the previous frame's segment where the surface is still there,
///     inside a held object), a region grows over the warp grid while the depth stays
///     continuous, never onto the floor (the dominant plane under the preprocess floor prior);
///     a region wider than max_object_width along the floor, higher than max_object_size above
///     it, or larger than max_object_size in a camera axis has leaked into static structure and
///     keeps only this frame's evidence. The segments, with the silhouette band in front of the
///     background, form DynamicObjects::pixel_mask. About 1.8 ms per frame with objects.
/// Objects are reported as DynamicObjects::boxes_3d (camera frame), so that the masker can gate
/// the keypoints by their depth range.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "ds3d/slam/orb_features.hpp"
#include "ds3d/slam/slam_frontend.hpp"

namespace ds3d::slam {

/// Parameters of GeometricMotionSource. Thresholds are statistical (χ², σ(z)) or metric; none is
/// tuned to a recorded sequence.
struct GeometricMotionParams {
  int num_features = 800;            ///< ORB features of the source's own extractor, > 0
  int reference_gap = 2;             ///< frames between the current and the reference frame, >= 1
  int max_match_distance = 50;       ///< Hamming distance of accepted matches, in [1, 256]
  float match_ratio = 0.8F;          ///< best / second-best Hamming distance below this, (0, 1]
  int ransac_iterations = 200;       ///< PnP-RANSAC iterations, >= 1
  double chi2_2dof = 5.991;          ///< χ²(2 dof, 95%) for the pose inlier test, > 0
  double moving_chi2 = 16.27;        ///< χ²(3 dof, 99.9%): a keypoint moves above this, > 0
  double min_pixel_sigma = 1.0;      ///< floor of the per-frame pixel noise σ_px [px], > 0
  float depth_noise = 1.5e-3F;       ///< σ(z) = depth_noise·z² [1/m], >= 0
  float min_depth_residual = 0.05F;  ///< depth residuals below this never flag (σ(z) floor =
                                     ///< this / 3) [m], > 0
  int depth_window = 2;           ///< half-size of the depth-spread window at keypoints [px], >= 0
  double min_inlier_ratio = 0.4;  ///< trusted pose: inliers / matches at least this, in [0, 1]
  int min_pose_inliers = 30;      ///< trusted pose: at least this many inliers, >= 6
  /// Motion prior of the source's own ego-motion [m/s²], >= 0 (0 = off). The constant-velocity
  /// prediction is the previous frame's trusted motion over the same reference gap, scaled to
  /// this gap's dt [s] (until the source has trusted a first motion, rest: a camera starts from
  /// standing still). A pose with the most inliers whose camera centre lies within
  /// max_acceleration · dt² of the prediction's is refined on its inliers with the prediction as
  /// a Gaussian prior on the camera centre (σ = max_acceleration · dt², the rotation free). When
  /// it lies farther, PnP-RANSAC runs again on the matches the prediction explains (within 2×
  /// the inlier threshold), and that pose, refined the same way, replaces the first one when it
  /// has min_pose_inliers inliers and lies less than half as far from the prediction. In front
  /// of a far wall a shift and a rotation move the image alike, and the matches alone leave the
  /// shift loose; a person walking across close to the camera moves it as a shift that a
  /// rotation makes fit the far background too, so the most inliers can be the person's
  /// (docs/dynamic.md). 10 m/s²: twice the hand-held recordings' p99 deviation from constant
  /// velocity.
  double max_acceleration = 10.0;
  /// Weak-consensus rule of the motion prior [inliers], >= 0 (0 = off): when the pose with the
  /// most inliers breaks the max_acceleration bound, no second hypothesis of min_pose_inliers
  /// inliers exists, and that pose has fewer inliers than this, the frame's pose is the
  /// prediction itself. Where people cover most of the view (crowd_cross seed 1, frames 8–10),
  /// 33 matches on a near walker form the largest consensus, 69 mm off over the two-frame gap,
  /// and as the next prediction it is accepted again; a camera does not accelerate like that.
  /// A strong consensus still wins: it is more likely the camera than a stale prediction.
  /// Default 60 = 2 × min_pose_inliers.
  int hold_prediction_inliers = 60;
  /// Frames between the current frame and the reference of the dense warp, >= 1. Longer
  /// baselines flag wider bands on walkers but, on recorded data (TUM fr1), also static edges:
  /// 4 and 6 were tried (docs/dynamic.md); the default is that of the pose.
  int warp_gap = 2;
  int warp_stride = 4;  ///< grid step of the dense depth warp [px], >= 1
  int warp_window = 3;  ///< half-size of the depth-edge / min-depth window of the warp [px], >= 0
  double warp_chi2 = 10.83;     ///< χ²(1 dof, 99.9%) of the warp's depth test, > 0
  double min_warp_area = 0.01;  ///< smallest warp candidate (metric area of its pixels) [m²], > 0
  /// Fastest object motion the warp explains as a receding surface [m/s], >= 0 (0 = off): a
  /// pixel behind the reference surface by more than its noise but less than max_speed · Δt
  /// (Δt from the frame timestamps) receded, as a person walking away from the camera; a larger
  /// step is a disocclusion and no evidence. 2 m/s is a brisk walk; running people need more.
  double max_speed = 2.0;
  /// The source's ORB runs on the image resized by this factor, in (0, 1]. 0.5 (a quarter of
  /// the pixels) cuts the source's instructions by a third, but finds fewer moving keypoints:
  /// Bonn crowd ATE 0.0228 m against 0.0209 m at 1 (docs/dynamic.md).
  double image_scale = 1.0;
  double max_depth = 6.0;    ///< depths beyond this are ignored [m], > 0
  int min_cluster_size = 6;  ///< HDBSCAN min_cluster_size (moving keypoints), >= 2
  int min_samples = 3;       ///< HDBSCAN min_samples, >= 1
  double min_support = 0.5;  ///< moving / tested keypoints in a cluster's region, in (0, 1]
  /// Support test of warp components, in [0, 1]; 0 (default) = none. A component passes when
  /// ≥ min_support of the tested cells in its rectangle moved, or ≥ this share of the tested
  /// cells within one cell of it (a solid band on a mover's body; pose-error flags along static
  /// edges are thin lines). At the default warp_gap 2 no test is needed: the static
  /// tum_fr1_xyz gives one component in 400 frames, while the test rejected most of a
  /// walker's leading-edge bands (synthetic keypoint recall 0.14-0.56 with 0.7, 0.44-0.80
  /// without; docs/dynamic.md). Use 0.7 with a longer warp_gap.
  double min_band_support = 0.0;
  double max_object_size =
      2.2;  ///< clusters larger than this in x, y or z are not objects [m], > 0
  /// Widest object segment along the floor [m], > 0: a walking person with swinging arms
  /// (shoulders about 0.5 m, a stride up to 1 m). A segment growing wider, or higher than
  /// max_object_size above the floor, has joined a wall or furniture and keeps its seeds only.
  double max_object_width = 1.2;
  float box_margin = 0.15F;  ///< object boxes grow by this in x, y and z [m], >= 0
  int hold_frames = 90;      ///< frames an object is kept after its last motion, >= 0
  /// Candidates of the first frame tested with a trusted pose (usually frame 1, against frame
  /// 0) become objects without the repeat of step 6 (key `geometric.trust_first_candidates`):
  /// no earlier frame can confirm them, and a front-end tracks that frame against a first map
  /// built from every keypoint of frame 0, people included. Off: the first objects come a frame
  /// later.
  bool trust_first_candidates = true;
  /// Grow each object over the depth-continuous surface around its evidence (step 6 of the file
  /// comment) and report it as DynamicObjects::pixel_mask. Off: boxes of the evidence only.
  bool segment_objects = true;
  void validate() const;  ///< throws ds3d::InvalidArgument naming the bad field
};

/// Statistics of the last detect() call.
struct GeometricMotionStats {
  bool pose_ok = false;          ///< a reference was available and the pose is trusted
  bool shared_orb = false;       ///< the features came from FrameInput::orb_corners
  int num_matches = 0;           ///< descriptor matches with the reference (reference depth)
  int num_pose_inliers = 0;      ///< PnP-RANSAC inliers
  bool prior_replaced = false;   ///< the motion prior replaced the largest-consensus pose
  bool prediction_held = false;  ///< the pose is the prior's prediction (hold_prediction_inliers)
  int num_tested = 0;            ///< keypoints with depth in both views that were χ²-tested
  int num_moving_keypoints = 0;  ///< tested keypoints above moving_chi2
  int num_warp_tested = 0;       ///< grid pixels tested by the dense depth warp
  int num_moving_pixels = 0;     ///< grid pixels flagged by the dense depth warp
  int num_warp_candidates = 0;   ///< candidates found by the warp alone (before merging)
  int num_candidates = 0;        ///< clusters that passed the size and support tests
  int num_new_objects = 0;       ///< candidates confirmed this frame
  int num_objects = 0;           ///< objects reported (new + held)
  int num_segments = 0;          ///< grown object segments in the pixel mask
  int num_segments_leaked = 0;   ///< regions that outgrew the object size (seeds kept only)
  int num_segment_cells = 0;     ///< warp grid cells in the pixel mask
  bool ground_found = false;     ///< a floor plane bounded the segments
  double pixel_sigma = 0;        ///< σ_px used this frame [px]
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< the source's own pose
};

/// One χ²-tested keypoint of the last detect() call (for diagnostics and visualisation).
struct TestedKeypoint {
  float u = 0;             ///< raw pixel column of the current frame
  float v = 0;             ///< raw pixel row of the current frame
  float z = 0;             ///< current depth [m]
  float chi2 = 0;          ///< χ² (3 dof) of its residual against the static prediction
  bool moving = false;     ///< chi2 > moving_chi2
  int cluster = -1;        ///< HDBSCAN cluster among the moving keypoints, -1 = none / not moving
  bool candidate = false;  ///< its cluster passed the size and support tests
};

/// The `geometric` dynamic-object source (see the file comment for the method).
/// @note Deterministic for a given frame sequence. Keeps state across frames: call detect() in
///       frame order (the SLAM pipeline does); not thread-safe. Cost per frame: one ORB
///       extraction (at image_scale; with FrameInput::orb_corners a selection and copy, about
///       1/30 of it), an O(N²) popcount Hamming match of N = num_features,
///       PnP-RANSAC, HDBSCAN on the moving keypoints only, two 7×7 min/max filters of the depth
///       and an O(pixels / warp_stride²) dense warp with connected components; about 90 M
///       instructions per 640×480 frame (docs/benchmarks.md).
class GeometricMotionSource final : public DynamicObjectSource {
 public:
  /// @throws ds3d::InvalidArgument on bad params.
  explicit GeometricMotionSource(const GeometricMotionParams& params = {});
  /// Moving objects of `frame` as 3-D boxes (camera frame). Frames without depth give nothing.
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  [[nodiscard]] std::string name() const override { return "geometric"; }
  /// True at image_scale 1: its features then come from FrameInput::orb_corners when given.
  [[nodiscard]] bool uses_orb_corners() const override { return params_.image_scale == 1.0; }
  /// Counters of the last detect() call (matches, moving keypoints, warp pixels, objects).
  [[nodiscard]] const GeometricMotionStats& last_stats() const noexcept { return stats_; }
  /// The parameters as validated by the constructor.
  [[nodiscard]] const GeometricMotionParams& params() const noexcept { return params_; }
  /// The keypoints tested in the last detect() call (empty without a trusted pose).
  [[nodiscard]] const std::vector<TestedKeypoint>& last_tested() const noexcept { return tested_; }
  /// The warp grid pixels (raw u, v) flagged as moved into empty space in the last detect() call.
  [[nodiscard]] const std::vector<Eigen::Vector2f>& last_moving_pixels() const noexcept {
    return moving_pixels_;
  }
  /// The warp grid pixels (raw u, v) that the dense depth warp tested in the last detect() call
  /// (flagged or not; a superset of last_moving_pixels()): the trials behind its false-alarm rate.
  [[nodiscard]] const std::vector<Eigen::Vector2f>& last_warp_tested() const noexcept {
    return warp_tested_;
  }

 private:
  struct Past {
    OrbFeatures features;  // at image_scale
    cv::Mat depth_small;   // CV_16UC1, the depth at image_scale (nearest)
    cv::Mat win_min;       // CV_16UC1, windowed minimum of the depth (0 if any pixel is missing)
    cv::Mat win_max;       // CV_16UC1, windowed maximum of the depth
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    bool pose_valid = false;  // T_world_cam is chained from trusted poses
    double timestamp = 0;     // [s]
  };
  struct Held {
    Eigen::Matrix<double, 8, 3> corners_world;  // the reported box (evidence + box_margin)
    Eigen::Vector3d lo_world, hi_world;         // its axis-aligned hull in the world frame
    std::size_t last_seen = 0;
  };
  struct PoseHypothesis {
    Eigen::Isometry3d T_cur_ref = Eigen::Isometry3d::Identity();
    cv::Mat rvec, tvec;  // OpenCV's form of T_cur_ref
    std::vector<int> inliers;
    bool ok = false;
  };
  struct Work;  // one frame's intermediate results (src/slam/dynamic/geometric_motion_impl.hpp)
  // The stages of detect(), in order (geometric_motion.cpp; the dense warp in geometric_warp.cpp).
  void extract_frame(const FrameInput& frame, const PinholeCamera& camera, Work& work);
  void select_reference(Work& work);
  void match_and_pose(Work& work);
  // Pieces of match_and_pose: PnP-RANSAC, its refinement on the inliers, the constant-velocity
  // prediction and the hypothesis choice of the motion prior (max_acceleration).
  [[nodiscard]] double inlier_threshold() const { return std::sqrt(params_.chi2_2dof) * 1.5; }
  [[nodiscard]] PoseHypothesis robust_pose(const std::vector<cv::Point3f>& obj,
                                           const std::vector<cv::Point2f>& img,
                                           const cv::Matx33d& K) const;
  static void refine_pose(const std::vector<cv::Point3f>& obj, const std::vector<cv::Point2f>& img,
                          const cv::Matx33d& K, PoseHypothesis& h);
  [[nodiscard]] std::optional<Eigen::Isometry3d> predicted_T_cur_ref(const Work& work) const;
  void apply_motion_prior(const Work& work, const std::vector<cv::Point3f>& obj,
                          const std::vector<cv::Point2f>& img, const cv::Matx33d& K,
                          PoseHypothesis& best);
  [[nodiscard]] double pixel_noise(const Work& work) const;
  void test_keypoints(Work& work);
  void cluster_keypoints(const PinholeCamera& camera, Work& work);
  void warp_depth(const FrameInput& frame, const PinholeCamera& camera, Work& work);
  void warp_candidates(const PinholeCamera& camera, Work& work);
  void merge_candidates(Work& work);
  void confirm_objects(std::size_t now, Work& work);
  void report_objects(const Work& work, DynamicObjects& out) const;
  GeometricMotionParams params_;
  OrbExtractor extractor_;
  std::deque<Past> history_;
  std::vector<Held> held_;
  std::vector<Held> candidates_;  // candidates of the previous frame, awaiting confirmation
  bool trusted_test_done_ = false;  // a frame was tested with a trusted pose (trust_first_...)
  std::vector<Eigen::Vector2d> grid_rays_;  // undistorted normalised ray of each warp grid pixel
  PinholeCamera grid_camera_{};             // camera grid_rays_ was computed for
  int grid_stride_ = 0;                     // stride grid_rays_ was computed for
  std::size_t frame_count_ = 0;
  Eigen::Isometry3d last_motion_ = Eigen::Isometry3d::Identity();  // last trusted T_cur_ref
  double last_motion_dt_ = 0;                                      // its time span [s]
  bool last_motion_valid_ = false;  // the previous frame's pose was trusted
  bool motion_seen_ = false;        // some frame's pose was trusted (before: predict rest)
  GeometricMotionStats stats_;
  std::vector<TestedKeypoint> tested_;
  std::vector<Eigen::Vector2f> moving_pixels_;
  std::vector<Eigen::Vector2f> warp_tested_;
  std::vector<Eigen::Vector3f> segment_world_;  // last frame's segment cells (world frame)
};

}  // namespace ds3d::slam

namespace ds3d::detail {
// Mutual best matches of two sets of 256-bit ORB descriptors (CV_8UC1 rows of 32 bytes) that pass
// Lowe's ratio test: d1 < ratio * d2 for the row of `a`, and that row is the best of `b`'s column
// (lowest index on ties). Equal to cv::BFMatcher(NORM_HAMMING) knnMatch(a, b, 2) + match(b, a).
// Empty when a has no rows, b fewer than 2, or either is not 32 bytes wide. Used by
// GeometricMotionSource; exposed for its test.
std::vector<cv::DMatch> mutual_ratio_matches(const cv::Mat& a, const cv::Mat& b, float ratio);
// The motion prior's pose refinement: T_cur_ref (reference points `obj` [m] seen at the
// undistorted pixels `img` of `camera`) refined on `inliers` (indices into obj and img) as a
// maximum a posteriori estimate, each reprojection error with σ_px [px] plus a Gaussian prior of
// σ_c [m] that the camera centre lies at the prediction's; the rotation free. Gauss-Newton from
// `T`, at most 10 steps; returns `T` unchanged for σ_px or σ_c not > 0 and stops at a
// non-finite step. Used by GeometricMotionSource; exposed for its test.
Eigen::Isometry3d refine_towards_prediction(const std::vector<cv::Point3f>& obj,
                                            const std::vector<cv::Point2f>& img,
                                            const std::vector<int>& inliers,
                                            const PinholeCamera& camera, Eigen::Isometry3d T,
                                            const Eigen::Isometry3d& pred, double sigma_px,
                                            double sigma_c);
}  // namespace ds3d::detail
