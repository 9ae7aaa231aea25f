// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file dynamic_sources.hpp
/// @brief Adapters that plug the dynamic-feature removal into the SLAM front-end's hooks
/// (ds3d::slam; OpenCV): FileSource (boxes from a JSON-lines detections file), HdbscanMasker
/// (DynamicFeatureFilter on the ORB keypoints), HtxSource (the HTx-lite 3-D detector on the
/// preprocessed depth), CompositeSource (two sources in sequence, e.g. `htx+geometric`), and
/// conversions between DynamicObjects and ImageBox lists. GeometricMotionSource (no learned
/// weights) is in geometric_motion.hpp.

#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "ds3d/box3.hpp"
#include "ds3d/dynamic/detections.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/preprocess/preprocess.hpp"
#include "ds3d/slam/dynamic/geometric_motion.hpp"
#include "ds3d/slam/slam_frontend.hpp"
#include "ds3d/htx/sparse_detector.hpp"

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
///
/// **Segmented boxes** (DynamicObjects::boxes_3d_segmented, e.g. HtxSource with segment): after
/// the filter, a dynamic keypoint that lies in no unsegmented box's image rectangle stays
/// dynamic only if its 3-D point (camera back-projection of its pixel and depth) lies within
/// DynamicObjects::foreground_radius of a foreground point and, when the source also gives
/// DynamicObjects::background_points, that foreground point is no farther than the nearest
/// background point (nearest-neighbour label transfer), and it does not lie on
/// DynamicObjects::segment_plane when one is given (within DynamicFilterParams::support_margin
/// plus 3σ of its depth noise along the normal: the floor the source removed before segmenting).
/// Conversely, a keypoint with depth that
/// the filter kept static although it passed the gates of a box (DynamicFilterResult::gated:
/// rectangle, depth range, support plane, solid) becomes dynamic when it lies in a segmented
/// box's rectangle, in no unsegmented one's, and passes that test (the filter's cluster choice
/// missed it: a desk in front took the foreground cluster, a seated person split in depth).
/// With DynamicObjects::segment_outside_boxes the whole image outside the unsegmented boxes'
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

/// Neighbours per point of smooth_segmentation.
inline constexpr std::size_t kSmoothingNeighbours = 12;

/// Spatial smoothing of a point segmentation (HtxSourceParams::segment_smoothing): mean-field
/// inference of a fully factorised binary conditional random field whose unaries are the
/// foreground logits u_i and whose pairwise term links each point with its kSmoothingNeighbours
/// nearest points closer than 2·kernel_width, with the Gaussian kernel
/// k_ij = exp(-d_ij² / kernel_width²). Starting from q_i = sigmoid(u_i), each
/// of `iterations` Jacobi steps sets q_i = sigmoid(u_i + weight · Σ_j k_ij (2 q_j − 1)); returns
/// the last step's logits u_i + weight · Σ_j k_ij (2 q_j − 1). A point whose neighbours are
/// confidently of the other label is relabelled; a boundary between two well-supported regions
/// stays where the unaries put it. Rows with a non-finite point or logit take no part and keep
/// their logit; weight 0 returns `logits` unchanged. Deterministic; O(n log n) for the
/// neighbours (a nanoflann KD-tree) and O(n·kSmoothingNeighbours) per step.
/// @param points       (n, 3) points [m], any frame.
/// @param logits       n foreground logits, one per row of `points`.
/// @param kernel_width Gaussian kernel width [m], finite, > 0 (HtxSource: the voxel leaf).
/// @param weight       pairwise weight, finite, >= 0.
/// @param iterations   mean-field steps, >= 1.
/// @throws ds3d::InvalidArgument on a size mismatch or a bad kernel_width, weight or iterations.
[[nodiscard]] std::vector<float> smooth_segmentation(const Points3f& points,
                                                     const std::vector<float>& logits,
                                                     double kernel_width, float weight,
                                                     int iterations = 5);

/// Keeps as foreground only the points of a segmentation that belong to a reported object:
/// those inside one of objects.boxes_3d (its solid, grown by `margin` per side) and those a
/// chain of foreground points, each within objects.foreground_radius of the next, connects to
/// them. The other finite foreground points move to objects.background_points (in their order,
/// after the existing rows): a segmenting detector's labels on furniture away from every object
/// it reported are not trusted (HtxSourceParams::segment_outside_boxes). Boxes whose corners are
/// not a cuboid anchor nothing; non-finite rows stay in foreground_points (the masker ignores
/// them). Deterministic; O(n log n) for the KD-tree plus one radius search per kept point.
/// @param objects the frame's objects; foreground_points and background_points are rewritten.
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
  /// masker keeps static (`ds3d-slam --floor`). Off by default: it raises precision on the
  /// synthetic scenes but removes fewer keypoints on recorded people (docs/dynamic.md). With
  /// segment the same floor always comes as DynamicObjects::segment_plane, which keeps it out of
  /// the segmentation's decisions only.
  bool report_floor = false;
  /// Run the detector's Part-A2 part head on every input point and report its foreground
  /// (probability > foreground_min_prob) and background points, every box flagged in
  /// boxes_3d_segmented: the masker keeps a box's dynamic keypoint only when its nearest
  /// segmented point is a foreground one within foreground_radius. On by default; needs the
  /// SparseDetector constructor (ignored with a DetectFn). See docs/dynamic.md.
  bool segment = true;
  float foreground_min_prob = 0.5F;  ///< foreground decision on the part head's sigmoid, (0, 1)
  /// DynamicObjects::foreground_radius reported [m], > 0, finite. Default 2 voxel leaves of the
  /// default preprocess (0.1 m): a keypoint lies within about one leaf of its voxel's centroid,
  /// and the nearest foreground centroid may be the next voxel's.
  float foreground_radius = 0.2F;
  /// Frames a box is carried after the detector reported it, >= 0 (0 = off; counted in detector
  /// runs with detect_every k > 1), default 10; needs segment. A held box is reported again
  /// unless a detected box continues it or fewer than hold_min_points foreground points of the
  /// frame lie in it (grown by box_uncertainty); it moves with their centroid. Covers detection
  /// misses of people the part head still sees (docs/dynamic.md). make_dynamic_source sets 0
  /// under an evidence gate ("htx&&geometric").
  int hold_frames = 10;
  int hold_min_points = 5;  ///< foreground points that keep a carried box, >= 1
  /// Longest time [s] a box is carried after its detection, finite, >= 0: with frames far apart
  /// (a sparse selection of a recording) the camera-frame box no longer fits.
  double hold_seconds = 0.5;
  /// Detector inputs drawn per frame (test-time augmentation), >= 1, default 1 = one pass; each
  /// draw costs one network pass. Needs segment. Each point's foreground logit is the mean over
  /// the draws that took it; a later draw's box is added unless a first-draw box continues it
  /// (as for hold_frames). See docs/dynamic.md.
  int draws = 1;
  /// Temporal smoothing of the segmentation, frames >= 0 (0 = off), default 10; needs segment.
  /// Each drawn point's foreground logit is averaged with that of its nearest drawn point within
  /// one preprocess voxel leaf (camera frame) in each of up to this many earlier frames no older
  /// than hold_seconds. Costs ≈ 3–4 ms per frame (docs/dynamic.md).
  int segment_frames = 10;
  /// Spatial smoothing of the segmentation, a weight >= 0, finite (0 = off, the default; needs
  /// segment): smooth_segmentation of the part head's (draw- and frame-averaged) logits with
  /// kernel width one preprocess voxel leaf (its largest edge), this weight and the default
  /// iterations. Costs ≈ 4 ms per frame at 4,096 drawn points (docs/dynamic.md).
  float segment_smoothing = 0.0F;
  /// Report the segmentation as covering the whole frame (DynamicObjects::segment_outside_boxes;
  /// needs segment), on by default: in frames with a box the masker also marks the keypoints
  /// outside the boxes that the segmentation test confirms. Only foreground connected to a
  /// reported box counts (keep_anchored_foreground with box_uncertainty; the rest is background,
  /// HtxFrameStats::num_unanchored). Off: the segmentation decides inside the boxes only. Not
  /// used under a motion gate ("htx&geometric", "htx&&geometric"). See docs/dynamic.md.
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
  std::size_t num_draw_boxes = 0;  ///< of num_boxes, added by draws after the first (draws)
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
  // The preprocess voxel leaf's largest edge [m]: the scale of both segmentation smoothings.
  [[nodiscard]] double largest_leaf_edge() const;
  DynamicObjects last_objects_;
  HtxFrameStats stats_;
  PixelRayCache rays_;  // undistortion table of the camera (distorted cameras only)
};

/// Two sources in sequence, 3DS-SLAM's semantic-then-geometric order: `first` runs on the frame;
/// `second` runs on the frame with the depth blanked (0 = no depth) inside the image boxes of
/// `first`'s objects, so it only sees, and estimates its own motion from, what `first` left as
/// static; the result is the union of both sources' objects (2-D boxes, 3-D boxes, and the
/// pixel masks OR-ed). The masker downstream then filters the keypoints of both sets of boxes.
/// @note Deterministic when both sources are. Not thread-safe (the sources keep state).
class CompositeSource final : public DynamicObjectSource {
 public:
  /// @throws ds3d::InvalidArgument when a source is null.
  CompositeSource(std::shared_ptr<DynamicObjectSource> first,
                  std::shared_ptr<DynamicObjectSource> second);
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  /// "<first>+<second>", e.g. "htx+geometric".
  [[nodiscard]] std::string name() const override;
  /// The source that runs first (e.g. the semantic detector).
  [[nodiscard]] const DynamicObjectSource& first() const noexcept { return *first_; }
  /// The source that runs second, on the depth left outside the first one's boxes.
  [[nodiscard]] const DynamicObjectSource& second() const noexcept { return *second_; }

 private:
  std::shared_ptr<DynamicObjectSource> first_;
  std::shared_ptr<DynamicObjectSource> second_;
};

/// Options of MotionGatedSource. The defaults are the overlap gate (`htx&geometric`);
/// `evidence` = true is the evidence gate (`htx&&geometric`, docs/dynamic.md).
struct MotionGateParams {
  /// Evidence gate: besides the overlap with the motion source's objects, a semantic box is kept
  /// when the motion source's raw, unconfirmed evidence inside it (χ²-tested keypoints and
  /// dense-warp grid pixels of this frame) is significantly above that source's false-alarm rate,
  /// and a box that overlaps a recently kept one is kept too (tracked). Needs the motion source to
  /// be a GeometricMotionSource; with any other it is the overlap gate.
  bool evidence = false;
  /// Per-keypoint χ² (3 dof) above which a tested keypoint inside a semantic box counts as moving,
  /// > 0. χ²₃(95 %) = 7.815: with a person detected, motion is a-priori likely, so the per-point
  /// level is relaxed from the source's 99.9 %; the box-level binomial test (alpha) bounds the
  /// false confirmations.
  double keypoint_chi2 = 7.815;
  /// Level of the one-sided binomial test of a box (moving keypoints, or flagged warp pixels,
  /// against the frame's false-alarm rate measured outside the semantic boxes), in (0, 1).
  /// 1e-4: a kept box is tracked for hold_frames (90) frames, so about 100 tests share a 1 %
  /// family-wise rate of false confirmations (Bonferroni).
  double alpha = 1e-4;
  bool pixel_evidence = true;  ///< also test the flagged warp pixels (not only the keypoints)
  int hold_frames = 90;        ///< a track is kept this many frames after its last box, >= 0
  /// Fastest object motion [m/s] when associating a box with a track, >= 0: the centres may lie
  /// apart by 3√2 · (box uncertainty) plus max_speed · Δt.
  double max_speed = 2.0;
  void validate() const;  ///< throws ds3d::InvalidArgument naming the bad field
};

/// A semantic source gated by a motion source (`htx&geometric`): both run on the whole frame;
/// a semantic object (2-D or 3-D box) is kept only where the motion source found something moving
/// in this frame: its image rectangle overlaps one of the motion source's image boxes (and, when
/// both carry a depth range, the depth ranges overlap) or contains pixels of its pixel mask. The
/// result is the motion source's objects plus the kept semantic boxes, which extend a mover's
/// evidence to the whole detected person. A detector that also boxes static furniture (the
/// synthetic-only HTx weights on real chairs and desks, models/README.md) then removes nothing on
/// a static scene, where `htx` alone removes the furniture's features and hurts tracking.
///
/// With MotionGateParams::evidence (`htx&&geometric`) a semantic 3-D box is also kept
/// on the geometric source's raw evidence inside it (its solid, or its rectangle and depth range):
/// k of the n tested keypoints with χ² > keypoint_chi2, or k of the n tested warp grid pixels
/// flagged, when P(X >= k) < alpha for X ~ Binomial(n, p0), with p0 the frame's rate of the same
/// evidence outside every semantic box (at least the test's nominal level): a person detection
/// makes motion a-priori likely, so the statistics of the box, not a confirmed object, decide.
/// Boxes are tracked in the world frame (the geometric source's pose): a box whose centre lies
/// within 3√2·(box uncertainty) + max_speed·Δt of a track's centre continues it. Evidence in two
/// consecutive frames of a track (the geometric source's rule for its candidates; one frame is
/// not enough on TUM fr1's static desk), or one overlapping motion object, confirms the track;
/// every box of a confirmed track is kept until hold_frames frames pass without evidence, so a
/// person who stops keeps being removed. 2-D boxes keep the overlap gate.
/// @note Deterministic when both sources are. Not thread-safe (the sources keep state).
class MotionGatedSource final : public DynamicObjectSource {
 public:
  /// @throws ds3d::InvalidArgument when a source is null or on bad params.
  MotionGatedSource(std::shared_ptr<DynamicObjectSource> semantic,
                    std::shared_ptr<DynamicObjectSource> motion, MotionGateParams params = {});
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  /// "<semantic>&<motion>", e.g. "htx&geometric" ("htx&&geometric" with the evidence gate).
  [[nodiscard]] std::string name() const override;
  /// Semantic boxes (2-D and 3-D) of the last detect() call, before the gate.
  [[nodiscard]] std::size_t last_semantic() const noexcept { return last_semantic_; }
  /// Semantic boxes of the last detect() call that the gate kept.
  [[nodiscard]] std::size_t last_kept() const noexcept { return last_kept_; }
  /// Kept boxes of the last detect() call that the overlap gate dropped and a confirmed track
  /// kept, with evidence in this frame (evidence gate).
  [[nodiscard]] std::size_t last_kept_by_evidence() const noexcept { return last_by_evidence_; }
  /// Kept boxes of the last detect() call that the overlap gate dropped and a confirmed track
  /// kept, without evidence in this frame (evidence gate: a person who stopped).
  [[nodiscard]] std::size_t last_kept_by_track() const noexcept { return last_by_track_; }
  /// The parameters in use (validated).
  [[nodiscard]] const MotionGateParams& params() const noexcept { return params_; }
  /// The semantic source (its boxes are gated).
  [[nodiscard]] const std::shared_ptr<DynamicObjectSource>& semantic() const noexcept {
    return semantic_;
  }
  /// The motion source (it gates the semantic boxes).
  [[nodiscard]] const std::shared_ptr<DynamicObjectSource>& motion() const noexcept {
    return motion_;
  }

 private:
  struct Track {
    Eigen::Vector3d centre_world = Eigen::Vector3d::Zero();
    double timestamp = 0;           // [s] of its last box
    std::size_t last_evidence = 0;  // frame (1-based count) of its last evidence
    bool confirmed = false;         // evidence in two consecutive frames, or a motion object
  };
  std::shared_ptr<DynamicObjectSource> semantic_;
  std::shared_ptr<DynamicObjectSource> motion_;
  MotionGateParams params_;
  std::vector<Track> tracks_;
  std::size_t frame_count_ = 0;
  std::size_t last_semantic_ = 0;
  std::size_t last_kept_ = 0;
  std::size_t last_by_evidence_ = 0;
  std::size_t last_by_track_ = 0;
};

/// Where the default HTx weights are looked for, in order: `<source tree>/models/NAME` (the
/// compile-time DS3D_SOURCE_DIR), `<install prefix>/share/ds3d/models/NAME` (configure-time
/// prefix), and `<directory of the running executable>/../share/ds3d/models/NAME` (a relocated
/// install). NAME is kDefaultHtxWeights.
[[nodiscard]] std::vector<std::filesystem::path> default_weights_candidates();
/// File name of the default weights.
inline constexpr const char* kDefaultHtxWeights = "htx_lite_fast.safetensors";
/// The first existing default_weights_candidates() entry.
/// @throws ds3d::IoError naming every path tried when none exists.
[[nodiscard]] std::filesystem::path find_default_weights();

/// Options of make_dynamic_source for the sources that take any.
struct DynamicSourceOptions {
  std::filesystem::path weights{};  ///< htx weights; empty = find_default_weights()
  HtxSourceParams htx{};            ///< htx parameters (detect_every, min_score, ...)
  GeometricMotionParams geometric{};  ///< geometric parameters
  FileSourceParams file{};          ///< file:PATH parameters
  MotionGateParams gate{};          ///< the gate of SlamConfig::gate (config.hpp)
};

/// Builds the source named by a `--dynamic` option value: "none", "file:PATH", "geometric"
/// (GeometricMotionSource with default parameters), "htx" (HtxSource, weights from `options`),
/// "A+B" with A and B any of these but none (CompositeSource: A, then B), e.g.
/// "htx+geometric", "A&B" (MotionGatedSource: A's boxes only where B sees motion), e.g.
/// "htx&geometric", or "A&&geometric" (MotionGatedSource with the evidence gate), e.g.
/// "htx&&geometric"; there A's htx source gets hold_frames = 0 (the gate's own tracks hold the
/// boxes it confirmed). A "file:" spec takes the rest of the string as its path.
/// @throws ds3d::InvalidArgument for an unknown name or bad options; ds3d::IoError for an
///   unreadable file or weights file (naming the path).
[[nodiscard]] std::shared_ptr<DynamicObjectSource> make_dynamic_source(
    const std::string& spec, const DynamicSourceOptions& options = {});

}  // namespace ds3d::slam
