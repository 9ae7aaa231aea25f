// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file slam_frontend.hpp
/// @brief A minimal ORB-SLAM2-style RGB-D SLAM front-end (tracking + local mapping) with the
/// dynamic-feature hooks of 3DS-SLAM (ds3d::slam; OpenCV + Ceres).
///
/// Method (Mur-Artal & Tardós 2017, "ORB-SLAM2", §III-A and §V, RGB-D case):
/// - each frame gets grid-spread ORB features with a depth each (orb_features.hpp);
/// - tracking predicts the pose with a constant-velocity model, matches the last frame's map
///   points by projection and optimises the pose (bundle_adjustment.hpp: Ceres, Huber, four χ²
///   rounds); it falls back to descriptor matching against the reference keyframe (+ PnP-RANSAC),
///   then to relocalisation against past keyframes; it then tracks the local map (points of the
///   covisible keyframes) and optimises again;
/// - a keyframe is inserted by ORB-SLAM2's policy; it creates map points from depth, updates the
///   covisibility graph, culls weak recent points and launches a local bundle adjustment over the
///   covisible window with the other observing keyframes fixed.
///
/// Between feature extraction and tracking sit the two stages 3DS-SLAM adds (Shen et al.): a
/// DynamicObjectSource (e.g. a 3-D detector) and a DynamicFeatureMasker (e.g. HDBSCAN-based
/// filtering) that marks keypoints on moving objects; marked keypoints never reach tracking.
/// The `none` implementations keep every feature.
///
/// Determinism: local BA runs in a mapping thread on a snapshot of the map, and its result is
/// applied exactly `ba_apply_lag` frames after the keyframe that launched it (tracking waits if
/// it is not done). Output is therefore identical with or without the thread, for any timing.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/slam/bundle_adjustment.hpp"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/slam/dynamic/objects.hpp"
#include "ds3d/slam/orb_features.hpp"

namespace ds3d::slam {

/// Configuration of SlamFrontend. Defaults follow ORB-SLAM2's TUM RGB-D settings.
struct FrontendConfig {
  PinholeCamera camera;          ///< intrinsics, distortion and depth scale of the input
  OrbParams orb;                 ///< feature extraction (orb.max_depth = close/far threshold)
  PoseOptimizerParams pose;      ///< pose-only optimisation
  LocalBaParams local_ba;        ///< local bundle adjustment
  double bf = 40.0;              ///< virtual stereo baseline × fx [px·m] for depth residuals, > 0
  int min_init_points = 100;     ///< keypoints with depth needed to start the map, >= 10
  int min_tracked_inliers = 30;  ///< local-map inliers for a frame to count as tracked, >= 10
  int keyframe_max_gap = 30;     ///< insert a keyframe at least every this many frames, >= 1
  int local_window = 10;         ///< keyframes optimised by local BA (covisible window), >= 2
  int max_fixed_keyframes = 20;  ///< other observing keyframes held fixed in local BA, >= 1
  bool enable_local_ba = true;   ///< run local BA on every new keyframe
  bool fuse_neighbors = false;   ///< merge duplicate map points with the covisible keyframes on
                                 ///< keyframe insertion (ORB-SLAM2's SearchInNeighbors + Fuse);
                                 ///< off by default: −3 % ATE on fr1_xyz but 5× worse on Bonn
                                 ///< crowd without a dynamic filter (docs/slam.md)
  bool mapping_thread = true;    ///< run local BA in its own thread (results are identical)
  bool final_global_ba = true;   ///< finish() runs a BA over all keyframes and points (first fixed)
  int ba_apply_lag = 3;  ///< frames after a keyframe at which its BA result is applied, >= 0
  int relocalisation_candidates = 30;  ///< most recent keyframes tried when lost, >= 1
  /// A frame after a lost one is first matched by projection against the map around the last
  /// tracked pose: the map points of the reference keyframe and its 10 best covisible keyframes
  /// projected at that pose (windows of 15, then 30 px × level scale, as the motion model), a
  /// pose-only optimisation (>= 20 inliers), then the local map; the frame counts as recovered
  /// (TrackState::kRelocalized) with min_tracked_inliers local-map inliers. Relocalisation
  /// (descriptor matching against one recent keyframe, 50 inliers) follows when this fails.
  /// While people still cover much of the view, the static map points around the last pose are
  /// often fewer than one keyframe's 50 but enough to hold the pose, and the map goes on instead
  /// of being re-anchored at a frozen pose. Off: relocalisation alone.
  bool recover_by_projection = true;
  int reanchor_after_lost = 10;  ///< consecutive lost frames after which a new map segment starts
                                 ///< at the last pose (0 = never), >= 0
  /// finish(): each map segment that a re-anchoring started and that is not yet in the first
  /// map's world is relocalised against the keyframes of the other segments, one of its
  /// keyframes at a time in order (nearest keyframes in time first, up to
  /// relocalisation_candidates; descriptor matching against one keyframe, then its local map,
  /// with relocalisation's 50 inliers); on success the segment, with any segment already merged
  /// into it, moves rigidly (keyframes and the map points they made) into that keyframe's world.
  /// A re-anchoring starts at the last known pose, displaced by the motion during the outage;
  /// this undoes that offset once the camera sees the earlier map again. Online poses
  /// (TrackResult) are not changed.
  bool merge_segments = true;
  /// finish(): a break in a map's frames (frames that are lost, or placed in a segment that
  /// never merged and appears only inside the break) between two frames of the same map world
  /// gets poses interpolated in time between those two frames (linear in the camera centre,
  /// slerp in rotation) instead of the last known pose. The frames keep their tracked flag.
  bool interpolate_lost = true;
  /// Spare ORB candidates kept per frame (the ones the even spread would pick next, with
  /// descriptors) to replace keypoints the dynamic filter removes, >= 0 (0 = off). In a frame
  /// where people cover much of the image most of the feature budget lands on them; the
  /// replacements keep the static background's share near orb.num_features. A spare candidate is
  /// used only outside every source box's image rectangle, off the source's pixel mask, and
  /// farther than one grid cell of its level (orb.cell_size × scale) from every removed keypoint.
  int spare_features = 0;
  /// When the map cannot be tracked (motion model, reference keyframe) or gives too few
  /// local-map inliers, match the last frame's static keypoints with depth (back-projected
  /// with its pose) and optimise the pose on them before falling back to relocalisation; a
  /// frame tracked so becomes a keyframe, so the map continues from it. Off: such frames are
  /// lost (and re-anchored after reanchor_after_lost frames).
  bool odometry_fallback = false;
  /// Motion gate: physical bounds of the camera's motion [m/s²], [rad/s²] (0 = off), >= 0.
  /// A tracked pose whose camera centre lies farther than max_acceleration · dt² from the
  /// constant-velocity prediction (dt = time since the last frame), or whose rotation differs
  /// from the prediction's by more than max_angular_acceleration · dt², is what matches on a
  /// moving object that dominates the frame produce. The frame is then tracked a second time
  /// from the prediction: the last frame's points matched at the predicted pose, only the
  /// matches that agree with it (4 × the χ² thresholds) start the pose-only optimisation, then
  /// the local map. That pose replaces the first one when it is within the same bounds and has
  /// min_tracked_inliers inliers; otherwise the first pose stays. The gate needs a velocity from
  /// two frames tracked in a row (not relocalised or re-anchored). The defaults, 60 m/s² and
  /// 60 rad/s², are far beyond a hand-held or robot-mounted camera (docs/slam.md, "Motion gate").
  double max_acceleration = 60;
  double max_angular_acceleration = 60;  ///< see max_acceleration
  /// Motion prior [m/s²], >= 0 (0 = off): with a dynamic source (not "none"), every pose-only
  /// optimisation of a frame whose constant-velocity prediction comes from two frames tracked in
  /// a row (as the motion gate's) adds a prior that the camera centre lies at the prediction's,
  /// σ = prior_acceleration · dt² per coordinate, Gaussian within 2 σ and with a constant pull
  /// beyond (Huber), the rotation free: the maximum a posteriori pose. In front of a far wall the
  /// matches leave a sideways shift paired with a rotation of shift / distance loose, and a few
  /// matches on a moving person the source missed then pull the pose along with them; the prior
  /// settles that direction. Without a source the people's matches shape the velocity too, and
  /// the prior would carry their drag on (docs/slam.md, "Motion prior"). Relocalisation and the
  /// odometry fallback do not use it.
  double prior_acceleration = 10;
  /// Source motion gate [m/s²], >= 0 (0 = off): when the dynamic source reports the camera's
  /// motion (DynamicObjects::ego_motion: the geometric source, alone or combined), a tracked
  /// pose whose camera centre lies farther than source_motion_gate · dt² (dt: from the source's
  /// reference frame to this one) from that motion applied to the reference frame's pose is
  /// tracked a second time from it, as the motion gate does from its prediction; the second
  /// pose replaces the first when it has min_tracked_inliers inliers and lies less than half as
  /// far from the source's motion. The source estimates its motion on two-frame matches only,
  /// outside the objects it holds, under its own motion prior, so it is not dragged by map
  /// points that were made on people before they were flagged (docs/slam.md, "Source motion
  /// gate").
  double source_motion_gate = 5;
  /// With the source motion gate: where the motion gate has refused the tracked pose as well
  /// (farther than max_acceleration / max_angular_acceleration from the constant-velocity
  /// prediction) and neither retry found a pose, the source's motion is the frame's pose, with
  /// the matches it explains (4 × the χ² thresholds). Two witnesses that never see the map then
  /// outvote a map whose points follow people who stood still when they were made (docs/slam.md,
  /// "Source motion gate").
  bool hold_source_motion = true;
  /// Keypoints on an occluding contour at a dynamic region are removed from tracking and
  /// mapping (0 = off), >= 0: those with a depth sample (at 4 and 8 px × their level's scale,
  /// 16 directions, and their own pixel) in a source box's image rectangle or on its pixel mask
  /// whose samples span a step, farthest depth > (1 + depth_edge_ratio) × nearest. Such a
  /// corner is formed by the person's silhouette against the background: it moves with the
  /// person, but its depth is the background's, so the dynamic filter keeps it as static.
  double depth_edge_ratio = 0;
  /// With a dynamic source (not "none"): at each keyframe, far keypoints (depth beyond
  /// orb.max_depth) of the previous keyframe that have no map point and that the new keyframe
  /// sees again, within 3 px × level scale of their projection, at a depth within 5 % and with a
  /// similar descriptor, become map points observed by both. One far depth is too noisy to make
  /// a point from; two agreeing views are not. Without a source it stays off: moving people
  /// far away agree across two views too, and nothing removes them.
  bool confirm_far_points = true;
  /// The depth term of every observation with depth [px of disparity bf/z], >= 0. 0: ORB-SLAM2's
  /// virtual right coordinate u_r = u − bf/z with the keypoint's octave σ, which caps what depth
  /// adds at what one more pixel coordinate adds. > 0: the disparity bf/z with this σ of its
  /// own (a Kinect-like sensor's σ_z ∝ z² is a constant disparity σ), so that depth constrains
  /// the pose as much as the sensor allows.
  double disparity_sigma = 0;
  double keyframe_ref_ratio = 0.75;  ///< a keyframe is needed when the frame tracks fewer than
                                     ///< this fraction of the reference keyframe's well-observed
                                     ///< points (ORB-SLAM2 RGB-D: 0.75), in (0, 1]
  /// finish(): re-optimise every tracked non-keyframe pose against the final map with the
  /// matches it was tracked with (pose-only, as in tracking); keyframes keep theirs. Keeps ≈ 50 B
  /// per match until finish() (≈ 20 kB a frame): turn off for very long sequences.
  bool refine_frame_poses = true;
  int refine_rounds = 2;  ///< after that refinement: rounds of (move every map point using all
                          ///< frames' matches, poses fixed; refine the frames again), >= 0
  /// finish(), after the global BA and before the refinement: the first this many input frames
  /// are matched again by projection against the final map, from the last of them back to the
  /// first, each starting from the new pose of the frame after it (the first tracked frame after
  /// them: its own pose); a frame takes its new pose and matches when it keeps
  /// min_tracked_inliers inliers. The first frames are tracked before any velocity exists and,
  /// with a source that needs a few frames to flag (geometric), before anything is flagged:
  /// where people fill the first map, the camera follows them for a few frames, while the final
  /// map has dropped their points (docs/stress.md). Keeps those frames' features until finish()
  /// (about 100 kB a frame). 0 = off (the default: on the recorded Bonn slices the online poses
  /// were the better ones, docs/stress.md), >= 0; 30 is the value measured.
  int retrack_first_frames = 0;
  /// [m/s²] After that refinement, finish() smooths the poses of all tracked frames (keyframes'
  /// frames included; keyframe_trajectory() keeps BA's) against the final map with this 1-σ of
  /// the camera's acceleration (smooth_poses(), pose_smoothing.hpp); 0 = off. A hand-held or
  /// robot-borne camera accelerates by a few m/s². Needs refine_frame_poses. >= 0.
  double smooth_acceleration = 3.0;
  /// Keyframe culling (local keyframe culling of ORB-SLAM, Mur-Artal, Montiel & Tardós 2015,
  /// §VI-E, as ORB-SLAM2's LocalMapping::KeyFrameCulling): after each local BA is applied, a
  /// covisible neighbour of the keyframe that launched it is removed when more than
  /// `keyframe_redundancy_ratio` of its close map points (depth <= orb.max_depth) are seen by at
  /// least `keyframe_redundant_observers` other keyframes at the same or a finer scale (octave <=
  /// its octave + 1). Keyframe 0, the current reference keyframe, keyframes newer than the
  /// launching one and keyframes in a pending BA snapshot are never removed. Frames keep their
  /// poses through a re-parenting. On by default: no keyframe is culled on fr1_xyz or Bonn crowd
  /// (identical output), and a 1,500-frame synthetic sequence keeps 217 of 383 keyframes at the
  /// same ATE (docs/slam.md).
  /// @note Costs O(covisible keyframes × their points × observations) per local BA.
  bool cull_keyframes = true;
  double keyframe_redundancy_ratio = 0.9;  ///< see cull_keyframes (ORB-SLAM2: 0.9), in (0, 1]
  int keyframe_redundant_observers = 3;    ///< see cull_keyframes (ORB-SLAM2: 3), >= 1
  void validate() const;                   ///< throws ds3d::InvalidArgument naming the bad field
};

/// Tracking state of a frame.
enum class TrackState : std::uint8_t {
  kNotInitialized,  ///< no map yet (not enough depth so far)
  kInitialized,     ///< this frame created the first keyframe
  kTracking,        ///< tracked against the map
  kRelocalized,     ///< recovered by relocalisation
  kLost,            ///< not tracked: the reported pose is the last known one (trajectory()
                    ///< after finish() may interpolate it: FrontendConfig::interpolate_lost)
  kReanchored,      ///< lost too long: a new map segment starts at the last known pose
};
/// Lower-case name of a TrackState ("tracking", "lost", ...).
[[nodiscard]] const char* to_string(TrackState s) noexcept;

/// Per-keypoint status in TrackResult::keypoint_status.
/// What became of a keypoint: unmatched, tracked (an inlier), removed by the dynamic filter,
/// or removed for lying on a depth edge (FrontendConfig::depth_edge_ratio).
enum class KeypointStatus : std::uint8_t {
  kUnmatched = 0,
  kTracked = 1,
  kDynamic = 2,
  kDepthEdge = 3
};

/// Per-stage times of one frame [ms]: wall time, and the CPU time of the thread that ran the
/// stage (CPU time does not grow when other processes compete for the cores).
struct StageTimes {
  double extract_ms = 0;      ///< ORB extraction (+ undistortion, depth lookup), wall
  double detect_ms = 0;       ///< dynamic-object source, wall (prepare_ms included)
  double prepare_ms = 0;      ///< of detect_ms: the source's prepare() (own thread when threaded)
  double filter_ms = 0;       ///< dynamic filter, wall
  double track_ms = 0;        ///< tracking (+ keyframe insertion, BA scheduling/applying), wall
  double extract_cpu_ms = 0;  ///< extraction, thread CPU time
  double track_cpu_ms = 0;    ///< tracking, thread CPU time
  double detect_cpu_ms = 0;   ///< dynamic-object source, thread CPU time (prepare_cpu_ms included)
  double prepare_cpu_ms = 0;  ///< of detect_cpu_ms: the source's prepare(), thread CPU time
};

/// The outcome of tracking one frame.
struct TrackResult {
  std::size_t index = 0;                                          ///< frame index
  double timestamp = 0;                                           ///< [s]
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< online estimate
  TrackState state = TrackState::kNotInitialized;                 ///< see TrackState
  bool tracked = false;   ///< state is kInitialized, kTracking or kRelocalized
  bool keyframe = false;  ///< this frame became a keyframe
  /// The pose came from frame-to-frame odometry (FrontendConfig::odometry_fallback): the map
  /// could not be tracked; the frame then became a keyframe.
  bool odometry = false;
  /// The first pose broke FrontendConfig::max_acceleration or max_angular_acceleration and the
  /// pose tracked from the constant-velocity prediction replaced it.
  bool motion_gated = false;
  int num_features = 0;  ///< keypoints extracted
  int num_dynamic = 0;   ///< keypoints the dynamic filter removed
  int num_refilled = 0;  ///< spare keypoints added in their place (FrontendConfig::spare_features)
  int num_depth_edge = 0;  ///< keypoints removed on depth edges (FrontendConfig::depth_edge_ratio)
  int num_inliers = 0;     ///< map-point matches kept by the last pose optimisation
  std::vector<cv::Point2f> keypoints;           ///< raw pixel of every extracted keypoint
  std::vector<KeypointStatus> keypoint_status;  ///< one per keypoint
  StageTimes times;                             ///< stage timings
};

/// A frame after the extraction and dynamic stages (what the tracking stage consumes).
struct PreparedFrame {
  FrameInput input;        ///< the frame itself
  OrbFeatures features;    ///< all extracted features
  DynamicObjects objects;  ///< from the dynamic-object source
  /// The source's prepare() result (prepare_dynamic); detect_dynamic consumes it.
  std::shared_ptr<const PreparedDetection> detection;
  std::vector<std::uint8_t> dynamic;  ///< one per feature, non-zero = removed
  /// Spare candidates of the extractor (FrontendConfig::spare_features); the dynamic stage
  /// appends the ones it uses to `features` (with dynamic = 0) and clears this.
  OrbFeatures spare;
  int num_refilled = 0;  ///< spare candidates appended to `features`
  StageTimes times;      ///< extract/detect/filter filled in
};

/// A timestamped pose (camera-to-world).
struct FramePose {
  std::size_t index = 0;                                          ///< frame index
  double timestamp = 0;                                           ///< [s]
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< camera → world
  bool tracked = false;  ///< false: carried over from the last tracked frame
};

/// A keyframe removed by keyframe culling (FrontendConfig::cull_keyframes), with the figures of
/// the redundancy test at the moment it was removed.
struct CulledKeyframe {
  std::size_t frame_index = 0;  ///< input frame that created the keyframe
  double timestamp = 0;         ///< [s]
  std::size_t at_frame = 0;     ///< input frame during which it was removed
  int close_points = 0;         ///< its map points with depth in (0, orb.max_depth]
  int redundant_points = 0;     ///< of those, points seen by enough other keyframes at <= scale+1
};

/// RGB-D SLAM front-end: feed frames in time order, read poses.
///
/// Usage: `SlamFrontend slam(cfg); for (...) { auto r = slam.track(rgb, depth, t); }
/// slam.finish(); auto traj = slam.trajectory();`
/// @note Not thread-safe: call track() from one thread. extract() and the const queries may be
///       called concurrently with each other, never concurrently with track()/finish().
class SlamFrontend {
 public:
  /// @throws ds3d::InvalidArgument on a bad config.
  explicit SlamFrontend(FrontendConfig config,
                        std::shared_ptr<DynamicObjectSource> source = nullptr,
                        std::shared_ptr<DynamicFeatureMasker> masker = nullptr);
  ~SlamFrontend();
  /// Moves the front-end; the source is left empty (only destruction and assignment are valid).
  SlamFrontend(SlamFrontend&&) noexcept;
  /// Move assignment; the source is left empty.
  SlamFrontend& operator=(SlamFrontend&&) noexcept;
  SlamFrontend(const SlamFrontend&) = delete;
  SlamFrontend& operator=(const SlamFrontend&) = delete;

  /// Runs every stage on one frame (on the calling thread) and returns its pose.
  /// @param rgb   CV_8UC3 BGR or CV_8UC1, camera size
  /// @param depth CV_16UC1 of the same size, or empty (then tracking relies on the map only)
  /// @param timestamp [s], finite, >= the previous frame's
  /// @throws ds3d::InvalidArgument on bad images or a timestamp earlier than the previous one.
  /// @note Never throws for lost tracking, black images or missing depth: see TrackResult::state.
  TrackResult track(const cv::Mat& rgb, const cv::Mat& depth, double timestamp);
  /// Same for a frame read by RgbdDataset (its index and timestamp are kept).
  TrackResult track(const RgbdFrame& frame);

  /// Stage 1 (thread-safe, const): validates the frame and extracts features; when the source
  /// uses them, the ORB corners go to input.orb_corners (detect_dynamic drops them).
  [[nodiscard]] PreparedFrame extract(FrameInput frame) const;
  /// Stage 2a (optional; in frame order, may run on another thread than the other stages, ahead
  /// of detect_dynamic of earlier frames): the frame-independent part of the dynamic-object
  /// source's work (DynamicObjectSource::prepare), kept in frame.detection.
  void prepare_dynamic(PreparedFrame& frame) const;
  /// Stage 2: runs the dynamic-object source (in frame order, after extract), with
  /// frame.detection if prepare_dynamic filled it (then cleared).
  void detect_dynamic(PreparedFrame& frame);
  /// Stage 3: runs the dynamic filter (in frame order, after detect_dynamic).
  void filter_dynamic(PreparedFrame& frame);
  /// Stage 4: tracks a prepared frame (in frame order).
  /// @throws ds3d::InvalidArgument when the timestamp is earlier than the previous frame's.
  TrackResult track_prepared(PreparedFrame frame);

  /// Waits for the mapping thread and applies any pending local BA, then (if
  /// config.merge_segments) moves re-anchored map segments back onto the earlier map, then (if
  /// config.final_global_ba) a global BA over all keyframes, then (if
  /// config.retrack_first_frames) matches the first frames again against the final map, then (if
  /// config.refine_frame_poses) re-optimises each tracked non-keyframe pose against the final map
  /// and smooths them, then (if config.interpolate_lost) interpolates the lost frames the map
  /// continues after. Call after the last frame; trajectory() reflects it. @note O(keyframes ·
  /// points) for the global BA (about a second for 400 frames) plus one pose-only optimisation
  /// per frame (a few ms each).
  void finish();

  /// One pose per tracked-or-not input frame, in input order. Each frame's pose is stored relative
  /// to its reference keyframe and re-expressed with that keyframe's latest (optimised) pose, as
  /// ORB-SLAM2 does when saving trajectories.
  [[nodiscard]] std::vector<FramePose> trajectory() const;
  /// One pose per live keyframe (camera → world), in creation order; culled keyframes are left
  /// out (their frames keep a pose in trajectory()).
  [[nodiscard]] std::vector<FramePose> keyframe_trajectory() const;
  /// Positions of all good map points [m, world frame], one row each.
  [[nodiscard]] Points3f map_points() const;
  /// Writes map_points() as an ASCII PLY file. @throws ds3d::IoError when it cannot be written.
  void write_map_ply(const std::filesystem::path& path) const;

  /// The configuration as validated by the constructor.
  [[nodiscard]] const FrontendConfig& config() const noexcept;
  /// Keyframes in the map so far (culled ones excluded).
  [[nodiscard]] std::size_t num_keyframes() const noexcept;
  /// Keyframes removed by keyframe culling so far, in removal order (see
  /// FrontendConfig::cull_keyframes).
  [[nodiscard]] const std::vector<CulledKeyframe>& culled_keyframes() const noexcept;
  /// Re-anchored map segments that finish() moved back onto another segment's map (see
  /// FrontendConfig::merge_segments); 0 before finish().
  [[nodiscard]] int merged_segments() const noexcept;
  /// Frames whose pose finish() interpolated (see FrontendConfig::interpolate_lost); 0 before
  /// finish().
  [[nodiscard]] int interpolated_frames() const noexcept;
  /// Local BAs run so far, and their total thread CPU time [ms] (measured in the mapping thread).
  [[nodiscard]] std::size_t num_local_ba() const noexcept;
  /// Total thread CPU time of the local BAs so far [ms] (see num_local_ba()).
  [[nodiscard]] double local_ba_ms() const noexcept;
  /// Thread CPU time of the pose and point refinement in finish() [ms] (0 before finish() or
  /// when config.refine_frame_poses is off).
  [[nodiscard]] double refine_ms() const noexcept;
  /// The dynamic-object source in use (NoDynamicObjects when none was given).
  [[nodiscard]] const DynamicObjectSource& dynamic_source() const noexcept;
  /// The dynamic-feature masker in use (NoDynamicMasker when none was given).
  [[nodiscard]] const DynamicFeatureMasker& dynamic_masker() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Drops the `tracked` flags: the poses as a ds3d::Trajectory (for write_tum_trajectory and
/// evaluate_ate).
[[nodiscard]] Trajectory to_trajectory(const std::vector<FramePose>& poses);

/// A dataset frame as tracking input: index, rgb timestamp and both images (moved, not copied;
/// `depth_timestamp` is dropped).
[[nodiscard]] inline FrameInput to_frame_input(RgbdFrame frame) {
  return FrameInput{frame.index, frame.timestamp, std::move(frame.rgb), std::move(frame.depth),
                    nullptr};
}

/// Options of run_pipeline.
struct PipelineOptions {
  bool threaded = true;    ///< stages in their own threads (false: all on the caller's)
  int queue_capacity = 2;  ///< frames buffered between consecutive stages, >= 1
  void validate() const;   ///< throws ds3d::InvalidArgument naming the bad field
};

/// Runs the stages over a sequence: ORB extraction beside the dynamic-object source (its
/// prepare(), for HTx the network, one frame ahead of its detection), then the dynamic filter,
/// then tracking, connected by bounded queues so that frame t+1 is extracted and detected while
/// frame t is tracked (3DS-SLAM runs detection beside ORB extraction). A source that reads the
/// frame's ORB corners (DynamicObjectSource::uses_orb_corners) detects after extraction instead.
/// @param slam   the front-end (its dynamic stages are used)
/// @param next   returns the next frame, or std::nullopt at the end; called from one thread
/// @param on_result called on the calling thread for every frame, in order (may be empty)
/// @param options threaded or not, queue capacity between stages
/// @return the results of all frames in order
/// @throws whatever a stage throws (rethrown on the caller after the threads stop).
/// @note Results are identical to calling track() on each frame (stages are pure or run in
///       frame order); finish() is called at the end.
std::vector<TrackResult> run_pipeline(SlamFrontend& slam,
                                      const std::function<std::optional<FrameInput>()>& next,
                                      const std::function<void(const TrackResult&)>& on_result = {},
                                      const PipelineOptions& options = {});

/// run_pipeline over the first `max_frames` frames of a dataset (images are read on the
/// pipeline's reader thread).
/// @param slam       the front-end (its dynamic stages are used)
/// @param dataset    an opened TUM/Bonn-layout dataset
/// @param max_frames 0 = all frames
/// @param on_result  called on the calling thread for every frame, in order (may be empty)
/// @param options    threaded or not, queue capacity between stages
/// @throws ds3d::IoError for unreadable images; what run_pipeline throws.
std::vector<TrackResult> run_dataset(SlamFrontend& slam, const RgbdDataset& dataset,
                                     std::size_t max_frames = 0,
                                     const std::function<void(const TrackResult&)>& on_result = {},
                                     const PipelineOptions& options = {});

}  // namespace ds3d::slam
