// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HtxSource: the HTx-lite 3-D detector (and its part-head segmentation) as a source.
#pragma once
/// @file htx_source.hpp
/// @brief The `htx` dynamic-object source, its options and per-frame stats, and
/// keep_anchored_foreground (ds3d::slam; OpenCV).

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ds3d/box3.hpp"
#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/htx/sparse_detector.hpp"
#include "ds3d/preprocess/preprocess.hpp"
#include "ds3d/slam/dynamic/objects.hpp"

namespace ds3d::slam {

/// Keeps as foreground only the points of a segmentation that belong to a reported object:
/// those inside one of objects.boxes_3d (its solid, grown by `margin` per side) and those a
/// chain of foreground points, each within objects.segmentation.foreground_radius of the next,
/// connects to them. The other finite foreground points move to the segmentation's
/// background_points (in their order, after the existing rows): a segmenting detector's labels
/// on furniture away from every object it reported are not trusted
/// (HtxSourceParams::segment_outside_boxes). Boxes whose corners are not a cuboid anchor
/// nothing; non-finite rows stay in foreground_points (the masker ignores them).
/// Deterministic; O(n log n) for the KD-tree plus one radius search per kept point.
/// @param objects the frame's objects; objects.segmentation's foreground_points and
///   background_points are rewritten.
/// @param margin growth of each box [m] per side, >= 0; +inf counts as 0 (the box itself).
/// @return how many foreground points moved to the background.
/// @throws ds3d::InvalidArgument on a negative or NaN margin or a bad foreground_radius.
std::size_t keep_anchored_foreground(DynamicObjects& objects, float margin);

/// Options of HtxSource.
struct HtxSourceParams {
  /// Depth → detector cloud (3DS-SLAM §III-B; preprocess.hpp). Its num_threads is replaced by
  /// HtxSourceParams::num_threads.
  PreprocessParams preprocess{};
  DetectorInputParams input{};  ///< points drawn for the detector (seed mixed with frame index)
  float min_score = 0.3F;  ///< boxes with a lower score p[class]·objectness are dropped, [0, 1]
  /// Class names (from the weights' config) treated as dynamic; empty = every class.
  std::vector<std::string> classes{"person"};
  int detect_every = 1;  ///< run the detector on every k-th frame (k >= 1); see HtxSource
  int num_threads = 1;   ///< threads of preprocess and the detector's attention; 0 = all, >= 0
  /// Metric uncertainty of the detector's boxes [m], >= 0, reported as
  /// DynamicObjects::boxes_3d_margin: the masker keeps only keypoints inside each oriented box
  /// grown by this much per side (plus 3σ of their depth noise); +inf gates by the projected
  /// rectangle and depth range alone (docs/dynamic.md).
  float box_uncertainty = 0.15F;
  /// Report the floor that preprocess found as DynamicObjects::support_plane, whose keypoints the
  /// masker keeps static (key `htx.report_floor`). Off by default: it raises precision on the
  /// synthetic scenes but removes fewer keypoints on recorded people (docs/dynamic.md). With
  /// segment the same floor always comes as Segmentation::segment_plane, which keeps it out of
  /// the segmentation's decisions only.
  bool report_floor = false;
  /// Run the detector's Part-A2 part head on every input point and report its foreground
  /// (probability > foreground_min_prob) and background points, every box flagged in
  /// boxes_3d_segmented: the masker keeps a box's dynamic keypoint only when its nearest
  /// segmented point is a foreground one within foreground_radius. On by default; needs the
  /// SparseDetector constructor (ignored with a DetectFn). See docs/dynamic.md.
  bool segment = true;
  float foreground_min_prob = 0.5F;  ///< foreground decision on the part head's sigmoid, (0, 1)
  /// Segmentation::foreground_radius reported [m], > 0, finite. Default 2 voxel leaves of the
  /// default preprocess (0.1 m): a keypoint lies within about one leaf of its voxel's centroid,
  /// and the nearest foreground centroid may be the next voxel's.
  float foreground_radius = 0.2F;
  /// Frames a box is carried after the detector reported it, >= 0 (0 = off; counted in detector
  /// runs with detect_every k > 1), default 30; needs segment. A held box is reported again
  /// unless a detected box continues it or fewer than hold_min_points foreground points of the
  /// frame lie in it (grown by box_uncertainty); it moves with their centroid. Covers detection
  /// misses of people the part head still sees, such as a person who stands close to the camera,
  /// cut by the image edges, for a second or more (docs/dynamic.md). make_dynamic_source sets 0
  /// under the evidence gate (`--gate evidence`) and at most 10 under the motion gate.
  int hold_frames = 30;
  int hold_min_points = 5;  ///< foreground points that keep a carried box, >= 1
  /// Longest time [s] a box is carried after its detection, finite, >= 0, default 1: with frames
  /// far apart (a sparse selection of a recording) the camera-frame box no longer fits. Also
  /// the oldest frame segment_frames averages over.
  double hold_seconds = 1.0;
  /// Temporal smoothing of the segmentation, frames >= 0 (0 = off), default 10; needs segment.
  /// Each drawn point's foreground logit is averaged with that of its nearest drawn point within
  /// one preprocess voxel leaf (camera frame) in each of up to this many earlier frames no older
  /// than hold_seconds. Costs ≈ 3–4 ms per frame (docs/dynamic.md).
  int segment_frames = 10;
  /// Report the segmentation as covering the whole frame (Segmentation::segment_outside_boxes;
  /// needs segment), on by default: in frames with a box the masker also marks the keypoints
  /// outside the boxes that the segmentation test confirms. Only foreground connected to a
  /// reported box counts (keep_anchored_foreground with box_uncertainty; the rest is background,
  /// HtxFrameStats::num_unanchored). Off: the segmentation decides inside the boxes only. Not
  /// used under a gate (`--gate motion` or `evidence`). See docs/dynamic.md.
  bool segment_outside_boxes = true;
  void validate() const;  ///< throws ds3d::InvalidArgument naming the bad field
};

/// What HtxSource did on the last frame.
struct HtxFrameStats {
  bool detected = false;  ///< the detector ran (false: frame skipped by detect_every, or no depth)
  std::size_t num_foreground = 0;  ///< input points segmented as foreground (segment only)
  bool ground_found = false;       ///< the gravity alignment came from this frame's floor plane
  std::size_t num_points = 0;      ///< preprocessed points (before the draw)
  std::size_t num_boxes = 0;       ///< boxes reported (after the class and score filters)
  std::size_t num_carried = 0;     ///< of num_boxes, carried from earlier frames (hold_frames)
  /// Foreground points reported as background because no chain of foreground points connects
  /// them to a reported box (segment_outside_boxes); not counted in num_foreground.
  std::size_t num_unanchored = 0;
  double preprocess_ms = 0;  ///< wall time of preprocess + draw [ms]
  double detect_ms = 0;      ///< wall time of the network + post-processing [ms]
};

/// The `htx` source (3DS-SLAM §III-B/C): per frame, preprocess() the depth image (back-projection,
/// voxels, ground removal, outliers), gravity-align the cloud with the floor normal
/// (upright_rotation; the last frame's alignment when no floor is found, the plain axis swap
/// before any floor was seen), draw the detector input (make_detector_input), detect() with the
/// HTx-lite network, keep boxes of the configured classes above min_score, and report them as
/// DynamicObjects::boxes_3d (corners in the camera frame), which HdbscanMasker projects into the
/// image (project_box) to gate its HDBSCAN filter.
///
/// With detect_every = k > 1 the detector runs on frames 0, k, 2k, ... of the sequence seen by
/// this source; frames in between reuse the last detection's 3-D boxes unchanged (camera-frame
/// corners, i.e. the object is assumed to stay where it was relative to the camera: the filter's
/// box margin and its own carried regions absorb the motion of a few frames).
/// @note Deterministic: the same frames in the same order give the same boxes (the draw's seed
///       is input.seed mixed with the frame index). Keeps state (alignment, last boxes): call in
///       frame order from one thread, as the pipeline's detection thread does.
class HtxSource final : public DynamicObjectSource {
 public:
  /// The 3-D detector: upright cloud [n, 3] → boxes in that frame (Box3::label indexes the
  /// class names). SparseDetector::detect by default; a test or another network can plug in here.
  using DetectFn = std::function<std::vector<Box3>(Eigen::Ref<const Points3f>)>;

  /// Uses a loaded detector (its config's class_names name the labels).
  /// @throws ds3d::InvalidArgument on bad params, or a class of params.classes that the
  ///   detector does not know (the message lists the known ones).
  explicit HtxSource(std::shared_ptr<const SparseDetector> detector, HtxSourceParams params = {});
  /// Uses any detection function. @throws like the other constructor; also for an empty `detect`.
  HtxSource(DetectFn detect, std::vector<std::string> class_names, HtxSourceParams params = {});

  /// Boxes of the configured classes in `frame` (camera-frame corners); none without depth.
  /// @throws ds3d::InvalidArgument only for a depth image of the wrong type or size.
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  /// The preprocessing and, when the frame's floor fixes the upright frame, the network pass of
  /// detect(): nullptr with detect_every > 1, with the DetectFn constructor (a plug-in function
  /// is not assumed thread-safe), or for an empty or invalid depth image (detect() reports it).
  /// Thread-safe against detect_prepared(); uses its own undistortion table.
  [[nodiscard]] std::shared_ptr<const PreparedDetection> prepare(
      const FrameInput& frame, const PinholeCamera& camera) const override;
  /// detect(), with the work prepare() did for this frame (same objects, same stats).
  /// @throws like detect().
  DynamicObjects detect_prepared(const FrameInput& frame, const PinholeCamera& camera,
                                 const PreparedDetection* prepared) override;
  [[nodiscard]] std::string name() const override { return "htx"; }
  /// Counts and timings of the last detect() call.
  [[nodiscard]] const HtxFrameStats& last_stats() const noexcept { return stats_; }
  /// The boxes of the last detection, in its upright frame (what the network returned, filtered).
  [[nodiscard]] const std::vector<Box3>& last_boxes() const noexcept { return boxes_; }
  /// The camera → upright rotation in use.
  [[nodiscard]] const Eigen::Matrix3f& R_up_cam() const noexcept { return R_up_cam_; }
  /// The parameters in use (validated).
  [[nodiscard]] const HtxSourceParams& params() const noexcept { return params_; }

 private:
  DetectFn detect_;
  // The full forward pass (boxes + part logits), only with the SparseDetector constructor.
  std::function<DetectorOutput(Eigen::Ref<const Points3f>)> run_;
  std::vector<std::int32_t> labels_;  // dynamic class indices; empty = all
  HtxSourceParams params_;
  Eigen::Matrix3f R_up_cam_;
  std::size_t frame_count_ = 0;
  // A box of an earlier detection (hold_frames): in the upright frame of its detection, with that
  // frame's camera -> upright rotation and its foreground centroid [m, camera frame].
  struct HeldBox {
    Box3 box;
    Eigen::Matrix3f R_up_cam;
    Eigen::Vector3f fg_centroid;
    double timestamp = 0;  // [s] of the detection
    int age = 0;           // frames since the detector reported it
  };
  // Foreground centroid of `fg` rows inside `b` (upright frame R) grown by box_uncertainty, and
  // their count.
  [[nodiscard]] std::pair<Eigen::Vector3f, int> foreground_in(const Box3& b,
                                                              const Eigen::Matrix3f& R,
                                                              const Points3f& fg) const;
  std::vector<Box3> boxes_;
  std::vector<HeldBox> held_;
  // An earlier frame's drawn points, their foreground logits and a KD-tree over them
  // (segment_frames; defined in the .cpp).
  struct PastSegmentation;
  std::deque<std::shared_ptr<const PastSegmentation>> past_;
  // segment_frames: replaces each drawn point's logit (count > 0) by its mean with the logit
  // of its nearest point within one voxel leaf in each earlier frame, and stores this frame's
  // (unsmoothed) logits.
  void smooth_over_frames(const Points3f& points, const std::vector<int>& count, double timestamp,
                          std::vector<float>& logit);
  // The preprocess voxel leaf's largest edge [m]: the scale of the temporal smoothing.
  [[nodiscard]] double largest_leaf_edge() const;
  // The segmentation stage of detect(): the network's part logits `o` on `in` averaged per
  // preprocessed point and over frames, and the points labelled into
  // last_objects_.segmentation. Returns the network's boxes.
  std::vector<Box3> segment_frame(const PreprocessResult& pre, const DetectorInput& in,
                                  const DetectorOutput& o, double timestamp);
  // The stateless stages of detect() (defined in the .cpp): the network's input and output, and
  // the preprocessed frame with, when its floor fixed the upright frame, the network's pass.
  struct Network;
  struct Prepared;
  [[nodiscard]] Prepared preprocess_frame(const FrameInput& frame, const PinholeCamera& camera,
                                          PixelRayCache& rays) const;
  [[nodiscard]] Network run_network(const PreprocessResult& pre, const Eigen::Matrix3f& R_up_cam,
                                    std::size_t index) const;
  DynamicObjects last_objects_;
  HtxFrameStats stats_;
  PixelRayCache rays_;                // undistortion table of the camera (distorted cameras only)
  mutable std::mutex prepare_mutex_;  // prepare() calls one at a time, with their own table
  mutable PixelRayCache prepare_rays_;
};

}  // namespace ds3d::slam
