// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Sources built from two sources: CompositeSource and MotionGatedSource.
#pragma once
/// @file combinators.hpp
/// @brief CompositeSource (`A+B`: two sources in sequence) and MotionGatedSource (`A&B`, `A&&B`:
/// a semantic source gated by a motion source) with MotionGateParams (ds3d::slam; OpenCV).

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ds3d/camera.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/slam/dynamic/objects.hpp"

namespace ds3d::slam {

/// Two sources in sequence, 3DS-SLAM's semantic-then-geometric order: `first`, then `second`,
/// each on the whole frame; the result is the union of both sources' objects (2-D boxes, 3-D
/// boxes, and the pixel masks OR-ed). The masker downstream then filters the keypoints of both
/// sets of boxes. `second` is not shown a frame with `first`'s objects removed: a motion source
/// needs the whole static background for its own ego-motion and must see the moving objects
/// `first` missed (a person cut by the image edge, a carried board).
/// @note Deterministic when both sources are. Not thread-safe (the sources keep state).
class CompositeSource final : public DynamicObjectSource {
 public:
  /// @throws ds3d::InvalidArgument when a source is null.
  CompositeSource(std::shared_ptr<DynamicObjectSource> first,
                  std::shared_ptr<DynamicObjectSource> second);
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  /// `first`'s prepare(); nullptr when it has none. `second` runs whole in detect_prepared().
  [[nodiscard]] std::shared_ptr<const PreparedDetection> prepare(
      const FrameInput& frame, const PinholeCamera& camera) const override;
  DynamicObjects detect_prepared(const FrameInput& frame, const PinholeCamera& camera,
                                 const PreparedDetection* prepared) override;
  /// True when either source reads FrameInput::orb_corners.
  [[nodiscard]] bool uses_orb_corners() const override;
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

/// Options of MotionGatedSource. The defaults are the motion gate (`--gate motion`);
/// `evidence` = true is the evidence gate (`--gate evidence`, docs/dynamic.md).
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
  /// Report the floor as the gated objects' support plane (key `gate.report_floor`), so that the
  /// masker keeps the keypoints on it static in every box: the semantic source's support plane,
  /// else the plane its segmentation left out (HtxSource: the floor its preprocessing found, at
  /// no extra cost), else the motion source's. Off: the semantic source's support plane, else
  /// the motion source's. On the crowd suite it helps both gates on every seed set; the same
  /// floor in `A+B` does not (docs/stress.md).
  bool report_floor = true;
  void validate() const;  ///< throws ds3d::InvalidArgument naming the bad field
};

/// A semantic source gated by a motion source (`--dynamic htx --gate motion`): both run on the
/// whole frame; a semantic object (2-D or 3-D box) is kept only where the motion source found
/// something moving in this frame: its image rectangle overlaps one of the motion source's image
/// boxes (and, when both carry a depth range, the depth ranges overlap) or contains pixels of its
/// pixel mask. The result is the motion source's objects plus the kept semantic boxes, which extend
/// a mover's evidence to the whole detected person. A detector that also boxes static furniture
/// (the synthetic-only HTx weights on real chairs and desks, models/README.md) then removes nothing
/// on a static scene, where `htx` alone removes the furniture's features and hurts tracking.
///
/// With MotionGateParams::evidence (`--gate evidence`) a semantic 3-D box is also kept
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
  /// Both sources' prepare(); nullptr when neither has one.
  [[nodiscard]] std::shared_ptr<const PreparedDetection> prepare(
      const FrameInput& frame, const PinholeCamera& camera) const override;
  DynamicObjects detect_prepared(const FrameInput& frame, const PinholeCamera& camera,
                                 const PreparedDetection* prepared) override;
  /// True when either source reads FrameInput::orb_corners.
  [[nodiscard]] bool uses_orb_corners() const override;
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
  // The evidence gate's tracking stage of detect(): associates the semantic 3-D boxes (`boxes`,
  // 2-D boxes first) with tracks_ in the world frame, confirms tracks on `evidence` (one flag
  // per box) and sets `keep` for the boxes of confirmed tracks.
  void track_boxes(double timestamp, std::size_t now, const DynamicObjects& sem,
                   const std::vector<std::optional<ImageBox>>& boxes,
                   const std::vector<std::uint8_t>& evidence, const Eigen::Isometry3d& T_world_cam,
                   std::vector<std::uint8_t>& keep);
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

}  // namespace ds3d::slam
