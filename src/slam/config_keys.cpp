// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The key table of SlamConfig: one row per key (name, field, help line), section by section.
// Adding a key: one row here; docs/configuration.md is regenerated from it (docs/contributing.md).
#include <vector>

#include "config_impl.hpp"

namespace ds3d::slam::detail_config {
namespace {

std::vector<ConfigKey> frontend_keys() {
  return {
      key(
          "frontend.bf", [](auto& c) -> auto& { return c.frontend.bf; },
          "virtual stereo baseline × fx [px·m] for depth residuals, > 0"),
      key(
          "frontend.min_init_points", [](auto& c) -> auto& { return c.frontend.min_init_points; },
          "keypoints with depth needed to start the map, >= 10"),
      key(
          "frontend.min_tracked_inliers",
          [](auto& c) -> auto& { return c.frontend.min_tracked_inliers; },
          "local-map inliers for a frame to count as tracked, >= 10"),
      key(
          "frontend.keyframe_max_gap", [](auto& c) -> auto& { return c.frontend.keyframe_max_gap; },
          "insert a keyframe at least every this many frames, >= 1"),
      key(
          "frontend.local_window", [](auto& c) -> auto& { return c.frontend.local_window; },
          "keyframes optimised by local BA (covisible window), >= 2"),
      key(
          "frontend.max_fixed_keyframes",
          [](auto& c) -> auto& { return c.frontend.max_fixed_keyframes; },
          "other observing keyframes held fixed in local BA, >= 1"),
      key(
          "frontend.enable_local_ba", [](auto& c) -> auto& { return c.frontend.enable_local_ba; },
          "run local BA on every new keyframe"),
      key(
          "frontend.fuse_neighbors", [](auto& c) -> auto& { return c.frontend.fuse_neighbors; },
          "merge duplicate map points with the covisible keyframes on"),
      key(
          "frontend.mapping_thread", [](auto& c) -> auto& { return c.frontend.mapping_thread; },
          "run local BA in its own thread (results are identical)"),
      key(
          "frontend.final_global_ba", [](auto& c) -> auto& { return c.frontend.final_global_ba; },
          "finish() runs a BA over all keyframes and points (first fixed)"),
      key(
          "frontend.ba_apply_lag", [](auto& c) -> auto& { return c.frontend.ba_apply_lag; },
          "frames after a keyframe at which its BA result is applied, >= 0"),
      key(
          "frontend.relocalisation_candidates",
          [](auto& c) -> auto& { return c.frontend.relocalisation_candidates; },
          "most recent keyframes tried when lost, >= 1"),
      key(
          "frontend.reanchor_after_lost",
          [](auto& c) -> auto& { return c.frontend.reanchor_after_lost; },
          "consecutive lost frames after which a new map segment starts"),
      key(
          "frontend.merge_segments", [](auto& c) -> auto& { return c.frontend.merge_segments; },
          "finish(): move each re-anchored map segment back onto the earlier map where it "
          "relocalises there"),
      key(
          "frontend.interpolate_lost", [](auto& c) -> auto& { return c.frontend.interpolate_lost; },
          "finish(): lost frames the map continues after get poses interpolated in time"),
      key(
          "frontend.recover_by_projection",
          [](auto& c) -> auto& { return c.frontend.recover_by_projection; },
          "after a lost frame, the last pose's local map by projection before relocalisation"),
      key(
          "frontend.spare_features", [](auto& c) -> auto& { return c.frontend.spare_features; },
          "spare ORB candidates that replace keypoints the dynamic filter removes (0 = off)"),
      key(
          "frontend.confirm_far_points",
          [](auto& c) -> auto& { return c.frontend.confirm_far_points; },
          "with a dynamic source: far keypoints seen again by the next keyframe at a consistent "
          "depth become map points"),
      key(
          "frontend.disparity_sigma", [](auto& c) -> auto& { return c.frontend.disparity_sigma; },
          "[px] sigma of the disparity bf/z of observations with depth (0 = ORB-SLAM2's u_right "
          "with the octave's sigma)"),
      key(
          "frontend.odometry_fallback",
          [](auto& c) -> auto& { return c.frontend.odometry_fallback; },
          "frame-to-frame odometry when the map cannot be tracked (the frame becomes a keyframe)"),
      key(
          "frontend.max_acceleration", [](auto& c) -> auto& { return c.frontend.max_acceleration; },
          "[m/s^2] a tracked pose farther than this x dt^2 from the constant-velocity "
          "prediction is rejected (0 = off)"),
      key(
          "frontend.max_angular_acceleration",
          [](auto& c) -> auto& { return c.frontend.max_angular_acceleration; },
          "[rad/s^2] a tracked rotation farther than this x dt^2 from the prediction's is "
          "rejected (0 = off)"),
      key(
          "frontend.prior_acceleration",
          [](auto& c) -> auto& { return c.frontend.prior_acceleration; },
          "[m/s^2] with a dynamic source, tracking adds a prior on the camera centre at the "
          "constant-velocity prediction, sigma = this x dt^2, Huber beyond 2 sigma (0 = off)"),
      key(
          "frontend.source_motion_gate",
          [](auto& c) -> auto& { return c.frontend.source_motion_gate; },
          "[m/s^2] a tracked camera centre farther than this x dt^2 from the dynamic source's "
          "own ego-motion (dt: since its reference frame) is tracked again from that motion "
          "(0 = off)"),
      key(
          "frontend.hold_source_motion",
          [](auto& c) -> auto& { return c.frontend.hold_source_motion; },
          "with the source motion gate: where the motion gate refused the pose too and neither "
          "retry found one, the source's ego-motion is the pose"),
      key(
          "frontend.depth_edge_ratio", [](auto& c) -> auto& { return c.frontend.depth_edge_ratio; },
          "keypoints on a depth step (far > (1 + ratio) x near) at a dynamic region are dropped (0 "
          "= off)"),
      key(
          "frontend.keyframe_ref_ratio",
          [](auto& c) -> auto& { return c.frontend.keyframe_ref_ratio; },
          "a keyframe is needed when the frame tracks fewer than"),
      key(
          "frontend.refine_frame_poses",
          [](auto& c) -> auto& { return c.frontend.refine_frame_poses; },
          "finish(): re-optimise every non-keyframe pose against the final map"),
      key(
          "frontend.refine_rounds", [](auto& c) -> auto& { return c.frontend.refine_rounds; },
          "after that refinement: rounds of (move every map point using all"),
      key(
          "frontend.retrack_first_frames",
          [](auto& c) -> auto& { return c.frontend.retrack_first_frames; },
          "finish(): the first this many frames are matched again against the final map, "
          "backwards from the frame after them (0 = off), >= 0"),
      key(
          "frontend.smooth_acceleration",
          [](auto& c) -> auto& { return c.frontend.smooth_acceleration; },
          "[m/s^2] finish(): smooth the frame poses with this 1-sigma camera acceleration (0 = "
          "off)"),
      key(
          "frontend.cull_keyframes", [](auto& c) -> auto& { return c.frontend.cull_keyframes; },
          "remove redundant keyframes (ORB-SLAM2's KeyFrameCulling)"),
      key(
          "frontend.keyframe_redundancy_ratio",
          [](auto& c) -> auto& { return c.frontend.keyframe_redundancy_ratio; },
          "see cull_keyframes (ORB-SLAM2: 0.9), in (0, 1]"),
      key(
          "frontend.keyframe_redundant_observers",
          [](auto& c) -> auto& { return c.frontend.keyframe_redundant_observers; },
          "see cull_keyframes (ORB-SLAM2: 3), >= 1"),
      key(
          "frontend.orb.num_features", [](auto& c) -> auto& { return c.frontend.orb.num_features; },
          "target number of features over all levels, > 0"),
      key(
          "frontend.orb.num_levels", [](auto& c) -> auto& { return c.frontend.orb.num_levels; },
          "pyramid levels, in [1, 16]"),
      key(
          "frontend.orb.scale_factor", [](auto& c) -> auto& { return c.frontend.orb.scale_factor; },
          "scale between consecutive levels, in (1, 2]"),
      key(
          "frontend.orb.fast_threshold",
          [](auto& c) -> auto& { return c.frontend.orb.fast_threshold; },
          "FAST intensity threshold, in [1, 255]"),
      key(
          "frontend.orb.min_fast_threshold",
          [](auto& c) -> auto& { return c.frontend.orb.min_fast_threshold; },
          "fallback threshold for cells with no corner, in [1, fast_threshold]"),
      key(
          "frontend.orb.cell_size", [](auto& c) -> auto& { return c.frontend.orb.cell_size; },
          "grid cell edge [px at that level], >= 8"),
      key(
          "frontend.orb.max_depth", [](auto& c) -> auto& { return c.frontend.orb.max_depth; },
          "keypoints up to this depth [m] are 'close' (ORB-SLAM2's ThDepth), > 0"),
      key(
          "frontend.orb.min_depth", [](auto& c) -> auto& { return c.frontend.orb.min_depth; },
          "depths below this [m] are treated as missing, >= 0"),
      key(
          "frontend.orb.max_range", [](auto& c) -> auto& { return c.frontend.orb.max_range; },
          "depths beyond this [m] are treated as missing, >= max_depth"),
      key(
          "frontend.pose.rounds", [](auto& c) -> auto& { return c.frontend.pose.rounds; },
          "optimisation rounds with outlier re-classification, >= 1"),
      key(
          "frontend.pose.iterations", [](auto& c) -> auto& { return c.frontend.pose.iterations; },
          "Levenberg-Marquardt iterations per round, >= 1"),
      key(
          "frontend.pose.chi2_mono", [](auto& c) -> auto& { return c.frontend.pose.chi2_mono; },
          "outlier threshold for 2-DoF observations, > 0"),
      key(
          "frontend.pose.chi2_stereo", [](auto& c) -> auto& { return c.frontend.pose.chi2_stereo; },
          "outlier threshold for 3-DoF observations, > 0"),
      key(
          "frontend.local_ba.iterations_first",
          [](auto& c) -> auto& { return c.frontend.local_ba.iterations_first; },
          "iterations before outlier removal, >= 1"),
      key(
          "frontend.local_ba.iterations_second",
          [](auto& c) -> auto& { return c.frontend.local_ba.iterations_second; },
          "iterations after outlier removal, >= 0"),
      key(
          "frontend.local_ba.chi2_mono",
          [](auto& c) -> auto& { return c.frontend.local_ba.chi2_mono; },
          "outlier threshold, 2 DoF, > 0"),
      key(
          "frontend.local_ba.chi2_stereo",
          [](auto& c) -> auto& { return c.frontend.local_ba.chi2_stereo; },
          "outlier threshold, 3 DoF, > 0"),
  };
}

std::vector<ConfigKey> orb_keys() { return {}; }

std::vector<ConfigKey> ba_keys() { return {}; }

std::vector<ConfigKey> htx_keys() {
  return {
      key(
          "htx.min_score", [](auto& c) -> auto& { return c.htx.min_score; },
          "boxes with a lower score p[class]·objectness are dropped, [0, 1]"),
      key(
          "htx.detect_every", [](auto& c) -> auto& { return c.htx.detect_every; },
          "run the detector on every k-th frame (k >= 1); see HtxSource"),
      key(
          "htx.num_threads", [](auto& c) -> auto& { return c.htx.num_threads; },
          "threads of preprocess and the detector's attention; 0 = all, >= 0"),
      key(
          "htx.box_uncertainty", [](auto& c) -> auto& { return c.htx.box_uncertainty; },
          "[m] per side; gate keypoints by the box's metric solid grown by this (+inf: rectangle "
          "and depth range only), >= 0"),
      key(
          "htx.report_floor", [](auto& c) -> auto& { return c.htx.report_floor; },
          "keypoints on the floor plane found by the detector's preprocessing stay static"),
      key(
          "htx.segment", [](auto& c) -> auto& { return c.htx.segment; },
          "confirm the boxes with the part head's foreground points"),
      key(
          "htx.foreground_min_prob", [](auto& c) -> auto& { return c.htx.foreground_min_prob; },
          "foreground decision on the part head's sigmoid, (0, 1)"),
      key(
          "htx.foreground_radius", [](auto& c) -> auto& { return c.htx.foreground_radius; },
          "[m] a keypoint is foreground within this distance of a foreground point, > 0"),
      key(
          "htx.hold_frames", [](auto& c) -> auto& { return c.htx.hold_frames; },
          "[frames] carry a box the detector missed while the part head sees foreground in it, >= "
          "0 (0 = off)"),
      key(
          "htx.hold_min_points", [](auto& c) -> auto& { return c.htx.hold_min_points; },
          "foreground points that keep a carried box, >= 1"),
      key(
          "htx.hold_seconds", [](auto& c) -> auto& { return c.htx.hold_seconds; },
          "[s] longest time a box is carried after its detection, >= 0"),
      key(
          "htx.segment_frames", [](auto& c) -> auto& { return c.htx.segment_frames; },
          "[frames] average each point's part-head logit over this many earlier frames, >= 0 (0 = "
          "off)"),
      key(
          "htx.segment_outside_boxes", [](auto& c) -> auto& { return c.htx.segment_outside_boxes; },
          "the part head also marks the keypoints it sees on people outside the boxes"),
  };
}

std::vector<ConfigKey> geometric_keys() {
  return {
      key(
          "geometric.num_features", [](auto& c) -> auto& { return c.geometric.num_features; },
          "ORB features of the source's own extractor, > 0"),
      key(
          "geometric.reference_gap", [](auto& c) -> auto& { return c.geometric.reference_gap; },
          "frames between the current and the reference frame, >= 1"),
      key(
          "geometric.max_match_distance",
          [](auto& c) -> auto& { return c.geometric.max_match_distance; },
          "Hamming distance of accepted matches, in [1, 256]"),
      key(
          "geometric.match_ratio", [](auto& c) -> auto& { return c.geometric.match_ratio; },
          "best / second-best Hamming distance below this, (0, 1]"),
      key(
          "geometric.ransac_iterations",
          [](auto& c) -> auto& { return c.geometric.ransac_iterations; },
          "PnP-RANSAC iterations, >= 1"),
      key(
          "geometric.chi2_2dof", [](auto& c) -> auto& { return c.geometric.chi2_2dof; },
          "χ²(2 dof, 95%) for the pose inlier test, > 0"),
      key(
          "geometric.moving_chi2", [](auto& c) -> auto& { return c.geometric.moving_chi2; },
          "χ²(3 dof, 99.9%): a keypoint moves above this, > 0"),
      key(
          "geometric.min_pixel_sigma", [](auto& c) -> auto& { return c.geometric.min_pixel_sigma; },
          "floor of the per-frame pixel noise σ_px [px], > 0"),
      key(
          "geometric.depth_noise", [](auto& c) -> auto& { return c.geometric.depth_noise; },
          "σ(z) = depth_noise·z² [1/m], >= 0"),
      key(
          "geometric.min_depth_residual",
          [](auto& c) -> auto& { return c.geometric.min_depth_residual; },
          "depth residuals below this never flag (σ(z) floor = ///< this / 3) [m], > 0"),
      key(
          "geometric.depth_window", [](auto& c) -> auto& { return c.geometric.depth_window; },
          "half-size of the depth-spread window at keypoints [px], >= 0"),
      key(
          "geometric.min_inlier_ratio",
          [](auto& c) -> auto& { return c.geometric.min_inlier_ratio; },
          "trusted pose: inliers / matches at least this, in [0, 1]"),
      key(
          "geometric.min_pose_inliers",
          [](auto& c) -> auto& { return c.geometric.min_pose_inliers; },
          "trusted pose: at least this many inliers, >= 6"),
      key(
          "geometric.max_acceleration",
          [](auto& c) -> auto& { return c.geometric.max_acceleration; },
          "[m/s^2] motion prior of the source's own pose: a pose within this * dt^2 of the "
          "constant-velocity prediction is refined with it as a prior on the camera centre (that "
          "sigma), a pose farther may be replaced by one the prediction explains, >= 0 (0 = off)"),
      key(
          "geometric.hold_prediction_inliers",
          [](auto& c) -> auto& { return c.geometric.hold_prediction_inliers; },
          "[inliers] a pose that breaks the motion prior with fewer inliers than this and no "
          "second hypothesis is replaced by the prediction itself, >= 0 (0 = off)"),
      key(
          "geometric.warp_gap", [](auto& c) -> auto& { return c.geometric.warp_gap; },
          "[frames] between the current frame and the reference of the dense depth warp, >= 1"),
      key(
          "geometric.warp_stride", [](auto& c) -> auto& { return c.geometric.warp_stride; },
          "grid step of the dense depth warp [px], >= 1"),
      key(
          "geometric.warp_window", [](auto& c) -> auto& { return c.geometric.warp_window; },
          "half-size of the depth-edge / min-depth window of the warp [px], >= 0"),
      key(
          "geometric.warp_chi2", [](auto& c) -> auto& { return c.geometric.warp_chi2; },
          "χ²(1 dof, 99.9%) of the warp's depth test, > 0"),
      key(
          "geometric.min_warp_area", [](auto& c) -> auto& { return c.geometric.min_warp_area; },
          "smallest warp candidate (metric area of its pixels) [m²], > 0"),
      key(
          "geometric.max_speed", [](auto& c) -> auto& { return c.geometric.max_speed; },
          "[m/s] fastest receding surface counted as motion evidence in the warp, > 0"),
      key(
          "geometric.image_scale", [](auto& c) -> auto& { return c.geometric.image_scale; },
          "the source's ORB runs on the image resized by this factor, in (0, 1]"),
      key(
          "geometric.max_depth", [](auto& c) -> auto& { return c.geometric.max_depth; },
          "depths beyond this are ignored [m], > 0"),
      key(
          "geometric.min_cluster_size",
          [](auto& c) -> auto& { return c.geometric.min_cluster_size; },
          "HDBSCAN min_cluster_size (moving keypoints), >= 2"),
      key(
          "geometric.min_samples", [](auto& c) -> auto& { return c.geometric.min_samples; },
          "HDBSCAN min_samples, >= 1"),
      key(
          "geometric.min_support", [](auto& c) -> auto& { return c.geometric.min_support; },
          "moving / tested keypoints in a cluster's region, in (0, 1]"),
      key(
          "geometric.min_band_support",
          [](auto& c) -> auto& { return c.geometric.min_band_support; },
          "moving / tested fraction required of a warp-only band, in [0, 1] (0 = off)"),
      key(
          "geometric.max_object_size", [](auto& c) -> auto& { return c.geometric.max_object_size; },
          "clusters larger than this in x, y or z are not objects [m], > 0"),
      key(
          "geometric.max_object_width",
          [](auto& c) -> auto& { return c.geometric.max_object_width; },
          "[m] widest object segment along the floor, > 0"),
      key(
          "geometric.box_margin", [](auto& c) -> auto& { return c.geometric.box_margin; },
          "object boxes grow by this in x, y and z [m], >= 0"),
      key(
          "geometric.hold_frames", [](auto& c) -> auto& { return c.geometric.hold_frames; },
          "frames an object is kept after its last motion, >= 0"),
      key(
          "geometric.trust_first_candidates",
          [](auto& c) -> auto& { return c.geometric.trust_first_candidates; },
          "candidates of the first frame tested with a trusted pose become objects without a "
          "repeat"),
      key(
          "geometric.segment_objects", [](auto& c) -> auto& { return c.geometric.segment_objects; },
          "grow each object over the depth-continuous surface around its evidence (pixel mask)"),
  };
}

std::vector<ConfigKey> filter_keys() {
  return {
      key(
          "gate.keypoint_chi2", [](auto& c) -> auto& { return c.gate_params.keypoint_chi2; },
          "per-keypoint chi2 (3 dof) above which a keypoint in a box counts as moving, > 0"),
      key(
          "gate.alpha", [](auto& c) -> auto& { return c.gate_params.alpha; },
          "level of the one-sided binomial test of a box's motion evidence, in (0, 1)"),
      key(
          "gate.pixel_evidence", [](auto& c) -> auto& { return c.gate_params.pixel_evidence; },
          "also test the flagged warp pixels (not only the keypoints)"),
      key(
          "gate.hold_frames", [](auto& c) -> auto& { return c.gate_params.hold_frames; },
          "a track is kept this many frames after its last box, >= 0"),
      key(
          "gate.max_speed", [](auto& c) -> auto& { return c.gate_params.max_speed; },
          "[m/s] fastest object motion when associating a box with a track, >= 0"),
      key(
          "gate.report_floor", [](auto& c) -> auto& { return c.gate_params.report_floor; },
          "keypoints on the floor (the semantic source's, or the plane its segmentation left "
          "out) stay static in every box"),
      key(
          "filter.min_score", [](auto& c) -> auto& { return c.filter.min_score; },
          "boxes with a lower score are ignored, in [0, 1]"),
      key(
          "filter.box_margin", [](auto& c) -> auto& { return c.filter.box_margin; },
          "each box grows by this fraction of its size per side, in [0, 1]"),
      key(
          "filter.min_cluster_size", [](auto& c) -> auto& { return c.filter.min_cluster_size; },
          "HDBSCAN min_cluster_size, >= 2"),
      key(
          "filter.min_samples", [](auto& c) -> auto& { return c.filter.min_samples; },
          "HDBSCAN min_samples (core distance k), >= 1"),
      key(
          "filter.min_keypoints", [](auto& c) -> auto& { return c.filter.min_keypoints; },
          "fewer depth keypoints in a box: depth-gap fallback, >= 2"),
      key(
          "filter.depth_gap", [](auto& c) -> auto& { return c.filter.depth_gap; },
          "largest depth gap [m] within one object, > 0"),
      key(
          "filter.max_object_depth", [](auto& c) -> auto& { return c.filter.max_object_depth; },
          "largest front-to-back extent of one object [m], > 0"),
      key(
          "filter.depth_noise", [](auto& c) -> auto& { return c.filter.depth_noise; },
          "sensor noise σ(z) = depth_noise·z² [1/m], >= 0"),
      key(
          "filter.min_vertical_span", [](auto& c) -> auto& { return c.filter.min_vertical_span; },
          "a foreground cluster spans at least this fraction of the"),
      key(
          "filter.carry_frames", [](auto& c) -> auto& { return c.filter.carry_frames; },
          "frames a dynamic region survives without a box, >= 0"),
      key(
          "filter.carry_iou", [](auto& c) -> auto& { return c.filter.carry_iou; },
          "a region overlapping a new box this much is not carried, (0, 1]"),
      key(
          "filter.carry_motion", [](auto& c) -> auto& { return c.filter.carry_motion; },
          "carried regions grow by this [m] (object motion per frame), >= 0"),
      key(
          "filter.support_margin", [](auto& c) -> auto& { return c.filter.support_margin; },
          "[m] keypoints within this distance of the support plane (+3 sigma) are static, >= 0"),
      key(
          "file.max_dt", [](auto& c) -> auto& { return c.file.max_dt; },
          "largest frame ↔ detection timestamp difference [s], >= 0"),
      key(
          "file.min_score", [](auto& c) -> auto& { return c.file.min_score; },
          "detections below this score are dropped, in [0, 1]"),
      key(
          "file.report_floor", [](auto& c) -> auto& { return c.file.report_floor; },
          "keypoints on the frame's floor (RANSAC on its depth) stay static in every box"),
      key(
          "file.hold_frames", [](auto& c) -> auto& { return c.file.hold_frames; },
          "frames a 3-D box is carried after the file last reported it (0 = off), >= 0"),
      key(
          "file.hold_min_points", [](auto& c) -> auto& { return c.file.hold_min_points; },
          "depth points that keep a carried box, >= 1"),
      key(
          "file.hold_margin", [](auto& c) -> auto& { return c.file.hold_margin; },
          "[m] a carried box grows by this per side when its points are gathered, >= 0"),
      key(
          "file.hold_seconds", [](auto& c) -> auto& { return c.file.hold_seconds; },
          "[s] longest time a box is carried after the file reported it, >= 0"),
      key(
          "pipeline.threaded", [](auto& c) -> auto& { return c.pipeline.threaded; },
          "stages in their own threads (false: all on the caller's)"),
      key(
          "pipeline.queue_capacity", [](auto& c) -> auto& { return c.pipeline.queue_capacity; },
          "frames buffered between consecutive stages, >= 1"),
      key(
          "pipeline.cv_threads", [](auto& c) -> auto& { return c.cv_threads; },
          "OpenCV's own worker threads, >= 0 (0 = OpenCV's default; the stages are the threads)"),
  };
}

}  // namespace

std::vector<ConfigKey> make_config_keys() {
  std::vector<ConfigKey> keys{
      key(
          "dynamic.source", [](auto& c) -> auto& { return c.dynamic; },
          "moving-object source: none, geometric, htx, file:PATH, mask:DIR or A+B (both on the "
          "whole frame, objects united)"),
      key(
          "dynamic.gate", [](auto& c) -> auto& { return c.gate; },
          "gate the source's boxes by the geometric source: none, motion or evidence"),
      key(
          "dynamic.weights", [](auto& c) -> auto& { return c.weights; },
          "HTx weights file (empty: the shipped models/htx_lite_fast.safetensors)"),
  };
  for (auto section : {frontend_keys, orb_keys, ba_keys, htx_keys, geometric_keys, filter_keys}) {
    for (auto& k : section()) keys.push_back(std::move(k));
  }
  return keys;
}

}  // namespace ds3d::slam::detail_config
