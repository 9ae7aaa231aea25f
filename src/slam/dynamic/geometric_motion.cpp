// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/dynamic/geometric_motion.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <utility>

#include <Eigen/Cholesky>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/slam/bundle_adjustment.hpp"
#include "geometric_motion_impl.hpp"

namespace ds3d::slam {

void GeometricMotionParams::validate() const {
  constexpr const char* f = "ds3d::slam::GeometricMotionParams";
  DS3D_CHECK(num_features > 0, f, ": num_features must be > 0 (got ", num_features, ")");
  DS3D_CHECK(reference_gap >= 1, f, ": reference_gap must be >= 1 (got ", reference_gap, ")");
  DS3D_CHECK(max_match_distance >= 1 && max_match_distance <= 256, f,
             ": max_match_distance must be in [1, 256] (got ", max_match_distance, ")");
  DS3D_CHECK(std::isfinite(match_ratio) && match_ratio > 0 && match_ratio <= 1, f,
             ": match_ratio must be in (0, 1] (got ", match_ratio, ")");
  DS3D_CHECK(ransac_iterations >= 1, f, ": ransac_iterations must be >= 1 (got ", ransac_iterations,
             ")");
  DS3D_CHECK(std::isfinite(chi2_2dof) && chi2_2dof > 0, f, ": chi2_2dof must be > 0 (got ",
             chi2_2dof, ")");
  DS3D_CHECK(std::isfinite(moving_chi2) && moving_chi2 > 0, f, ": moving_chi2 must be > 0 (got ",
             moving_chi2, ")");
  DS3D_CHECK(std::isfinite(min_pixel_sigma) && min_pixel_sigma > 0, f,
             ": min_pixel_sigma must be > 0 (got ", min_pixel_sigma, ")");
  DS3D_CHECK(std::isfinite(depth_noise) && depth_noise >= 0, f, ": depth_noise must be >= 0 (got ",
             depth_noise, ")");
  DS3D_CHECK(std::isfinite(min_depth_residual) && min_depth_residual > 0, f,
             ": min_depth_residual must be > 0 (got ", min_depth_residual, ")");
  DS3D_CHECK(depth_window >= 0, f, ": depth_window must be >= 0 (got ", depth_window, ")");
  DS3D_CHECK(std::isfinite(min_inlier_ratio) && min_inlier_ratio >= 0 && min_inlier_ratio <= 1, f,
             ": min_inlier_ratio must be in [0, 1] (got ", min_inlier_ratio, ")");
  DS3D_CHECK(min_pose_inliers >= 6, f, ": min_pose_inliers must be >= 6 (got ", min_pose_inliers,
             ")");
  DS3D_CHECK(std::isfinite(max_acceleration) && max_acceleration >= 0, f,
             ": max_acceleration must be finite and >= 0 (got ", max_acceleration, ")");
  DS3D_CHECK(hold_prediction_inliers >= 0, f, ": hold_prediction_inliers must be >= 0 (got ",
             hold_prediction_inliers, ")");
  DS3D_CHECK(warp_stride >= 1, f, ": warp_stride must be >= 1 (got ", warp_stride, ")");
  DS3D_CHECK(warp_gap >= 1, f, ": warp_gap must be >= 1 (got ", warp_gap, ")");
  DS3D_CHECK(warp_window >= 0, f, ": warp_window must be >= 0 (got ", warp_window, ")");
  DS3D_CHECK(std::isfinite(warp_chi2) && warp_chi2 > 0, f, ": warp_chi2 must be > 0 (got ",
             warp_chi2, ")");
  DS3D_CHECK(std::isfinite(min_warp_area) && min_warp_area > 0, f,
             ": min_warp_area must be > 0 (got ", min_warp_area, ")");
  DS3D_CHECK(std::isfinite(max_object_width) && max_object_width > 0, f,
             ": max_object_width must be > 0 (got ", max_object_width, ")");
  DS3D_CHECK(std::isfinite(max_speed) && max_speed >= 0, f, ": max_speed must be >= 0 (got ",
             max_speed, ")");
  DS3D_CHECK(std::isfinite(min_band_support) && min_band_support >= 0 && min_band_support <= 1, f,
             ": min_band_support must be in [0, 1] (got ", min_band_support, ")");
  DS3D_CHECK(std::isfinite(image_scale) && image_scale > 0 && image_scale <= 1, f,
             ": image_scale must be in (0, 1] (got ", image_scale, ")");
  DS3D_CHECK(std::isfinite(max_depth) && max_depth > 0, f, ": max_depth must be > 0 (got ",
             max_depth, ")");
  DS3D_CHECK(min_cluster_size >= 2, f, ": min_cluster_size must be >= 2 (got ", min_cluster_size,
             ")");
  DS3D_CHECK(min_samples >= 1, f, ": min_samples must be >= 1 (got ", min_samples, ")");
  DS3D_CHECK(std::isfinite(min_support) && min_support > 0 && min_support <= 1, f,
             ": min_support must be in (0, 1] (got ", min_support, ")");
  DS3D_CHECK(std::isfinite(max_object_size) && max_object_size > 0, f,
             ": max_object_size must be > 0 (got ", max_object_size, ")");
  DS3D_CHECK(std::isfinite(box_margin) && box_margin >= 0, f, ": box_margin must be >= 0 (got ",
             box_margin, ")");
  DS3D_CHECK(hold_frames >= 0, f, ": hold_frames must be >= 0 (got ", hold_frames, ")");
}

namespace {

OrbParams orb_params(const GeometricMotionParams& p) {
  OrbParams o;
  o.num_features = p.num_features;
  o.max_depth = p.max_depth;
  o.max_range = std::max(o.max_range, p.max_depth);
  return o;
}

// Ray through an undistorted pixel (z = 1).
Eigen::Vector3d ray(const PinholeCamera& c, const Eigen::Vector2f& u) {
  return {(u.x() - c.cx) / c.fx, (u.y() - c.cy) / c.fy, 1.0};
}

// Spread (max - min) of the valid depths [m] in a (2r+1)² window around (u, v); 0 if < 2 valid.
double depth_spread(const cv::Mat& depth, double scale, float u, float v, int r) {
  const int x0 = static_cast<int>(std::lround(u));
  const int y0 = static_cast<int>(std::lround(v));
  std::uint16_t lo = std::numeric_limits<std::uint16_t>::max();
  std::uint16_t hi = 0;
  for (int y = std::max(0, y0 - r); y <= std::min(depth.rows - 1, y0 + r); ++y) {
    const auto* row = depth.ptr<std::uint16_t>(y);
    for (int x = std::max(0, x0 - r); x <= std::min(depth.cols - 1, x0 + r); ++x) {
      if (row[x] == 0) continue;
      lo = std::min(lo, row[x]);
      hi = std::max(hi, row[x]);
    }
  }
  return hi > lo ? (hi - lo) / scale : 0.0;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The camera of an image resized to (w, h): intrinsics scaled about the pixel-centre convention;
// distortion is in normalised coordinates and does not change.
PinholeCamera resized_camera(const PinholeCamera& c, int w, int h) {
  PinholeCamera o = c;
  const double sx = static_cast<double>(w) / c.width;
  const double sy = static_cast<double>(h) / c.height;
  o.fx = c.fx * sx;
  o.fy = c.fy * sy;
  o.cx = (c.cx + 0.5) * sx - 0.5;
  o.cy = (c.cy + 0.5) * sy - 0.5;
  o.width = w;
  o.height = h;
  return o;
}

using detail::Box3;
using detail::edge_thr;
using detail::sigma_z;

}  // namespace

}  // namespace ds3d::slam

namespace ds3d::detail {

// Mutual best matches of two sets of 256-bit ORB descriptors (rows of CV_8UC1, 32 bytes) that
// pass Lowe's ratio test (Lowe 2004, §7.1), by one brute-force pass over all pairs that keeps the
// best and second best per row of `a` and the best per row of `b`. Same result as
// BFMatcher::knnMatch(a, b, 2) + BFMatcher::match(b, a) with the lowest index winning ties, at a
// fraction of the cost (hardware popcount, no per-call allocations of OpenCV's batch distance).
std::vector<cv::DMatch> mutual_ratio_matches(const cv::Mat& a, const cv::Mat& b, float ratio) {
  std::vector<cv::DMatch> out;
  if (a.rows == 0 || b.rows < 2 || a.cols != 32 || b.cols != 32) return out;
  const auto pack = [](const cv::Mat& m) {
    std::vector<std::array<std::uint64_t, 4>> v(static_cast<std::size_t>(m.rows));
    for (int r = 0; r < m.rows; ++r)
      std::memcpy(v[static_cast<std::size_t>(r)].data(), m.ptr(r), 32);
    return v;
  };
  const auto pa = pack(a);
  const auto pb = pack(b);
  const int na = a.rows;
  const int nb = b.rows;
  std::vector<int> best_of_b(static_cast<std::size_t>(nb), std::numeric_limits<int>::max());
  std::vector<int> best_idx_b(static_cast<std::size_t>(nb), -1);
  std::vector<std::array<int, 3>> best_of_a(static_cast<std::size_t>(na));  // d1, d2, index
  for (int i = 0; i < na; ++i) {
    const auto& x = pa[static_cast<std::size_t>(i)];
    int d1 = std::numeric_limits<int>::max();
    int d2 = d1;
    int j1 = -1;
    for (int j = 0; j < nb; ++j) {
      const auto& y = pb[static_cast<std::size_t>(j)];
      const int d = std::popcount(x[0] ^ y[0]) + std::popcount(x[1] ^ y[1]) +
                    std::popcount(x[2] ^ y[2]) + std::popcount(x[3] ^ y[3]);
      if (d < d1) {
        d2 = d1;
        d1 = d;
        j1 = j;
      } else if (d < d2) {
        d2 = d;
      }
      if (d < best_of_b[static_cast<std::size_t>(j)]) {
        best_of_b[static_cast<std::size_t>(j)] = d;
        best_idx_b[static_cast<std::size_t>(j)] = i;
      }
    }
    best_of_a[static_cast<std::size_t>(i)] = {d1, d2, j1};
  }
  for (int i = 0; i < na; ++i) {
    const auto [d1, d2, j1] = best_of_a[static_cast<std::size_t>(i)];
    if (j1 < 0 || !(static_cast<float>(d1) < ratio * static_cast<float>(d2))) continue;
    if (best_idx_b[static_cast<std::size_t>(j1)] != i) continue;
    out.emplace_back(i, j1, static_cast<float>(d1));
  }
  return out;
}

}  // namespace ds3d::detail

namespace ds3d::slam {

namespace {

// Distance between the camera centres of two poses T_cur_ref that share the reference [m].
double centre_gap(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse() * b).translation().norm();
}

}  // namespace

GeometricMotionSource::GeometricMotionSource(const GeometricMotionParams& params)
    : params_((params.validate(), params)), extractor_(orb_params(params)) {}

DynamicObjects GeometricMotionSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  stats_ = {};
  const std::size_t now = frame_count_++;
  DynamicObjects out;
  tested_.clear();
  moving_pixels_.clear();
  warp_tested_.clear();
  if (frame.depth.empty() || frame.depth.type() != CV_16UC1 || frame.rgb.empty()) return out;
  if (frame.depth.cols != camera.width || frame.depth.rows != camera.height) return out;

  Work work;
  extract_frame(frame, camera, work);
  select_reference(work);
  work.pixel_sigma = params_.min_pixel_sigma;
  if (work.ref != nullptr) {
    // The motion is reported only where it agrees with the motion prior's prediction: a first
    // motion after a restart, or a strong consensus far from the prediction, is the largest
    // consensus alone, which people who cover most of the view can win.
    if (params_.max_acceleration > 0.0) work.pred = predicted_T_cur_ref(work);
    match_and_pose(work);
    if (stats_.pose_ok) {
      work.cur.T_world_cam = work.ref->T_world_cam * work.T_cur_ref.inverse();
      work.cur.pose_valid = true;
      const double dt = work.cur.timestamp - work.ref->timestamp;
      if (work.pred &&
          centre_gap(*work.pred, work.T_cur_ref) <= params_.max_acceleration * dt * dt) {
        out.ego_motion = EgoMotion{work.ref->timestamp, work.T_cur_ref};
      }
      work.pixel_sigma = pixel_noise(work);
      test_keypoints(work);
    }
  }
  stats_.pixel_sigma = work.pixel_sigma;
  cluster_keypoints(camera, work);
  // The warp grid (full resolution, stride s, first pixel s/2): cell c ↔ pixel (u, v).
  detail::WarpGrid& g = work.grid;
  g.s = params_.warp_stride;
  g.off = g.s / 2;
  g.gw = camera.width > g.off ? (camera.width - 1 - g.off) / g.s + 1 : 0;
  g.gh = camera.height > g.off ? (camera.height - 1 - g.off) / g.s + 1 : 0;
  if (stats_.pose_ok && g.gw > 0 && g.gh > 0) {
    warp_depth(frame, camera, work);
    warp_candidates(camera, work);
  }
  merge_candidates(work);
  confirm_objects(now, work);
  stats_.T_world_cam = work.cur.T_world_cam;

  // 6b. Object segments: each object's evidence covers only what moved into empty space (the
  //     leading band of a walker) and its matched keypoints; grow it over the depth-continuous
  //     surface it lies on, as a pixel mask.
  std::vector<Eigen::Vector3f> segment_world;
  if (params_.segment_objects && work.cur.pose_valid && !g.state.empty() &&
      (!work.confirmed.empty() || (!held_.empty() && !segment_world_.empty()))) {
    const detail::SegmentCounts sc = detail::grow_segments(
        params_, frame.depth, camera, work.cur.T_world_cam, work.confirmed, !held_.empty(), tested_,
        segment_world_, g, &out.pixel_mask, &segment_world);
    stats_.num_segment_cells = sc.cells;
    stats_.num_segments = sc.segments;
    stats_.num_segments_leaked = sc.leaked;
    stats_.ground_found = sc.ground_found;
  }
  segment_world_ = std::move(segment_world);
  report_objects(work, out);
  stats_.num_objects = static_cast<int>(out.boxes_3d.size());

  history_.push_back(std::move(work.cur));
  while (static_cast<int>(history_.size()) > std::max(params_.reference_gap, params_.warp_gap)) {
    history_.pop_front();
  }
  return out;
}

// The source's ORB features at image_scale and the windowed depth range of the current frame.
void GeometricMotionSource::extract_frame(const FrameInput& frame, const PinholeCamera& camera,
                                          Work& work) {
  // The source's own ORB runs on a reduced image (its camera `cs`); the dense warp and the
  // reported boxes use the full-resolution depth and `camera`.
  const int sw = std::max(1, static_cast<int>(std::lround(camera.width * params_.image_scale)));
  const int sh = std::max(1, static_cast<int>(std::lround(camera.height * params_.image_scale)));
  work.cs = resized_camera(camera, sw, sh);
  const PinholeCamera& cs = work.cs;
  work.kx = static_cast<double>(camera.width) / sw;  // small → full pixel scale
  work.ky = static_cast<double>(camera.height) / sh;
  Past& cur = work.cur;
  cur.timestamp = frame.timestamp;
  if (sw == camera.width && sh == camera.height) {
    // A copy: the source keeps it for reference_gap frames, and the caller's buffer may be
    // reused or freed meanwhile (a cv::Mat over external memory, a numpy array).
    cur.depth_small = frame.depth.clone();
    // The front-end's corners of this image, when it passed them on and the pyramids agree.
    std::optional<OrbFeatures> shared;
    if (frame.orb_corners != nullptr) {
      shared = extractor_.extract_from(*frame.orb_corners, frame.depth, cs);
    }
    stats_.shared_orb = shared.has_value();
    cur.features = shared ? std::move(*shared) : extractor_.extract(frame.rgb, frame.depth, cs);
  } else {
    cv::Mat rgb_small;
    cv::resize(frame.rgb, rgb_small, cv::Size(sw, sh), 0, 0, cv::INTER_AREA);
    cv::resize(frame.depth, cur.depth_small, cv::Size(sw, sh), 0, 0, cv::INTER_NEAREST);
    cur.features = extractor_.extract(rgb_small, cur.depth_small, cs);
  }
  {
    // Windowed min (0 wherever a pixel of the window lacks depth) and max: depth edges and holes.
    const int k = 2 * params_.warp_window + 1;
    const cv::Mat se = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k));
    cv::erode(frame.depth, cur.win_min, se);
    cv::dilate(frame.depth, cur.win_max, se);
  }
}

void GeometricMotionSource::select_reference(Work& work) {
  Past& cur = work.cur;
  // Reference: the oldest remembered frame whose world pose is chained from trusted poses. With
  // none (a long run of untrusted poses), the world frame of held objects is lost: restart.
  const Past*& ref = work.ref;
  const std::size_t first_ref =
      history_.size() - std::min(history_.size(), static_cast<std::size_t>(params_.reference_gap));
  for (std::size_t h = first_ref; h < history_.size(); ++h) {
    if (history_[h].pose_valid) {
      ref = &history_[h];
      break;
    }
  }
  if (ref == nullptr) {
    held_.clear();
    candidates_.clear();
    if (!history_.empty()) ref = &history_.back();
  }
  cur.T_world_cam = ref != nullptr ? ref->T_world_cam : Eigen::Isometry3d::Identity();
  cur.pose_valid = history_.empty();  // the first frame defines the world frame
}

// 1. and 2.: matches with the reference, and the robust pose T_cur_ref.
void GeometricMotionSource::match_and_pose(Work& work) {
  const Past& cur = work.cur;
  const Past* ref = work.ref;
  const PinholeCamera& cs = work.cs;
  std::vector<std::pair<std::size_t, std::size_t>>& pairs = work.pairs;  // (current, reference)
  Eigen::Isometry3d& T_cur_ref = work.T_cur_ref;
  const auto inside_held = [&](const Eigen::Vector3d& p_world) {
    return std::any_of(held_.begin(), held_.end(), [&](const Held& h) {
      const Eigen::Vector3d lo = h.corners_world.colwise().minCoeff().transpose();
      const Eigen::Vector3d hi = h.corners_world.colwise().maxCoeff().transpose();
      return (p_world.array() >= lo.array()).all() && (p_world.array() <= hi.array()).all();
    });
  };
  // 1. Mutual best matches that also pass Lowe's ratio test (Lowe 2004, §7.1): repeated texture
  // (keyboards, tiles) gives ambiguous descriptors whose mismatches share one wrong offset and
  // would form a dense "moving" cluster on static structure.
  const std::vector<cv::DMatch> matches = ds3d::detail::mutual_ratio_matches(
      cur.features.descriptors, ref->features.descriptors, params_.match_ratio);
  std::vector<cv::Point3f> obj;
  std::vector<cv::Point2f> img;
  std::vector<cv::Point3f> obj_all;
  std::vector<cv::Point2f> img_all;
  for (const cv::DMatch& m : matches) {
    if (m.distance > static_cast<float>(params_.max_match_distance)) continue;
    const auto c = static_cast<std::size_t>(m.queryIdx);
    const auto r = static_cast<std::size_t>(m.trainIdx);
    if (!ref->features.has_depth(r)) continue;
    const Eigen::Vector3d p = ref->features.depth[r] * ray(cs, ref->features.undistorted[r]);
    const cv::Point3f pf(static_cast<float>(p.x()), static_cast<float>(p.y()),
                         static_cast<float>(p.z()));
    const cv::Point2f uc(cur.features.undistorted[c].x(), cur.features.undistorted[c].y());
    pairs.emplace_back(c, r);
    obj_all.push_back(pf);
    img_all.push_back(uc);
    if (!inside_held(ref->T_world_cam * p)) {
      obj.push_back(pf);
      img.push_back(uc);
    }
  }
  stats_.num_matches = static_cast<int>(pairs.size());
  // Known objects covering most matches would starve the pose: then use every match.
  if (static_cast<int>(obj.size()) < 2 * params_.min_pose_inliers) {
    obj = obj_all;
    img = img_all;
  }
  // 2. Robust pose T_cur_ref (EPnP-RANSAC, then Levenberg-Marquardt on the inliers). The
  //    inlier threshold is in pixels of the reduced image.
  if (static_cast<int>(obj.size()) >= params_.min_pose_inliers) {
    const cv::Matx33d K(cs.fx, 0, cs.cx, 0, cs.fy, cs.cy, 0, 0, 1);
    PoseHypothesis best = robust_pose(obj, img, K);
    stats_.num_pose_inliers = static_cast<int>(best.inliers.size());
    const double ratio = static_cast<double>(best.inliers.size()) /
                         static_cast<double>(std::max<std::size_t>(obj.size(), 1));
    if (best.ok && static_cast<int>(best.inliers.size()) >= params_.min_pose_inliers &&
        ratio >= params_.min_inlier_ratio) {
      refine_pose(obj, img, K, best);
      apply_motion_prior(work, obj, img, K, best);
      T_cur_ref = best.T_cur_ref;
      stats_.pose_ok = T_cur_ref.matrix().allFinite();
    }
  }
  last_motion_valid_ = stats_.pose_ok;
  motion_seen_ = motion_seen_ || stats_.pose_ok;
  if (stats_.pose_ok) {
    last_motion_ = T_cur_ref;
    last_motion_dt_ = cur.timestamp - ref->timestamp;
  }
}

GeometricMotionSource::PoseHypothesis GeometricMotionSource::robust_pose(
    const std::vector<cv::Point3f>& obj, const std::vector<cv::Point2f>& img,
    const cv::Matx33d& K) const {
  PoseHypothesis h;
  h.ok = cv::solvePnPRansac(obj, img, K, cv::noArray(), h.rvec, h.tvec, false,
                            params_.ransac_iterations, static_cast<float>(inlier_threshold()), 0.99,
                            h.inliers, cv::SOLVEPNP_EPNP);
  return h;
}

void GeometricMotionSource::refine_pose(const std::vector<cv::Point3f>& obj,
                                        const std::vector<cv::Point2f>& img, const cv::Matx33d& K,
                                        PoseHypothesis& h) {
  std::vector<cv::Point3f> oi;
  std::vector<cv::Point2f> ii;
  for (const int i : h.inliers) {
    oi.push_back(obj[static_cast<std::size_t>(i)]);
    ii.push_back(img[static_cast<std::size_t>(i)]);
  }
  cv::solvePnP(oi, ii, K, cv::noArray(), h.rvec, h.tvec, true, cv::SOLVEPNP_ITERATIVE);
  cv::Mat R;
  cv::Rodrigues(h.rvec, R);
  Eigen::Matrix3d Re;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) Re(a, b) = R.at<double>(a, b);
  }
  h.T_cur_ref.linear() = Re;
  h.T_cur_ref.translation() =
      Eigen::Vector3d(h.tvec.at<double>(0), h.tvec.at<double>(1), h.tvec.at<double>(2));
}

std::optional<Eigen::Isometry3d> GeometricMotionSource::predicted_T_cur_ref(
    const Work& work) const {
  if (work.ref == nullptr) return std::nullopt;
  // Before the first trusted motion: at rest. People in view from the first frame can otherwise
  // make the first motion theirs, and every later prediction with it.
  if (!motion_seen_) return Eigen::Isometry3d::Identity();
  if (!last_motion_valid_) return std::nullopt;
  const double dt = work.cur.timestamp - work.ref->timestamp;
  if (!(last_motion_dt_ > 0.0) || !(dt > 0.0)) return std::nullopt;
  // Constant velocity in the camera frame: the last trusted motion over the same gap, scaled
  // to this gap's duration.
  const double s = dt / last_motion_dt_;
  const Eigen::AngleAxisd aa(last_motion_.linear());
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.linear() = Eigen::AngleAxisd(aa.angle() * s, aa.axis()).toRotationMatrix();
  p.translation() = last_motion_.translation() * s;
  return p;
}

void GeometricMotionSource::apply_motion_prior(const Work& work,
                                               const std::vector<cv::Point3f>& obj,
                                               const std::vector<cv::Point2f>& img,
                                               const cv::Matx33d& K, PoseHypothesis& best) {
  const std::optional<Eigen::Isometry3d>& pred = work.pred;
  if (!pred) return;
  const double dt = work.cur.timestamp - work.ref->timestamp;
  const PinholeCamera& cs = work.cs;
  // σ_px: the pixel noise the inlier threshold assumes; σ_c: the bound itself.
  const double sigma_px = inlier_threshold() / std::sqrt(params_.chi2_2dof);
  const double sigma_c = params_.max_acceleration * dt * dt;
  const double gap_best = centre_gap(best.T_cur_ref, *pred);
  if (!(gap_best > sigma_c)) {
    // Within the bound: the pose is the maximum a posteriori one under the prediction.
    best.T_cur_ref = ds3d::detail::refine_towards_prediction(
        obj, img, best.inliers, cs, best.T_cur_ref, *pred, sigma_px, sigma_c);
    return;
  }
  // The largest consensus is far from the prediction: a near mover whose motion, with a
  // rotation, also fits the far background. The matches the prediction explains (within 2×
  // the inlier threshold) give the other hypothesis. In front of a far wall a wider window lets
  // the prediction explain the mover's matches as well, and the second RANSAC finds it again.
  const double gate = 2.0 * inlier_threshold();
  std::vector<cv::Point3f> og;
  std::vector<cv::Point2f> ig;
  for (std::size_t i = 0; i < obj.size(); ++i) {
    const Eigen::Vector3d q = *pred * Eigen::Vector3d(obj[i].x, obj[i].y, obj[i].z);
    if (q.z() <= 0.0) continue;
    const double du = cs.fx * q.x() / q.z() + cs.cx - img[i].x;
    const double dv = cs.fy * q.y() / q.z() + cs.cy - img[i].y;
    if (std::hypot(du, dv) > gate) continue;
    og.push_back(obj[i]);
    ig.push_back(img[i]);
  }
  PoseHypothesis other;
  if (static_cast<int>(og.size()) >= params_.min_pose_inliers) other = robust_pose(og, ig, K);
  if (!other.ok || static_cast<int>(other.inliers.size()) < params_.min_pose_inliers) {
    // No second hypothesis. A weak first one is more likely a near mover than a camera
    // accelerating beyond the bound: the prediction is the pose (constant velocity).
    if (static_cast<int>(best.inliers.size()) < params_.hold_prediction_inliers) {
      best.T_cur_ref = *pred;
      stats_.prediction_held = true;
    }
    return;
  }
  refine_pose(og, ig, K, other);
  other.T_cur_ref = ds3d::detail::refine_towards_prediction(
      og, ig, other.inliers, cs, other.T_cur_ref, *pred, sigma_px, sigma_c);
  if (centre_gap(other.T_cur_ref, *pred) < 0.5 * gap_best) {
    best = std::move(other);
    stats_.prior_replaced = true;
  }
}

double GeometricMotionSource::pixel_noise(const Work& work) const {
  const Past& cur = work.cur;
  const Past* ref = work.ref;
  const PinholeCamera& cs = work.cs;
  const auto& pairs = work.pairs;
  const Eigen::Isometry3d& T_cur_ref = work.T_cur_ref;
  // σ_px of this frame: the median reprojection error of all matches, in level-0 pixels per
  // pyramid scale, over the median of a 2-D Rayleigh (σ·√(2 ln 2)). Robust up to half the
  // matches being outliers, and it grows with blur and rolling-shutter distortion.
  std::vector<double> e;
  for (const auto& [c, r] : pairs) {
    const Eigen::Vector3d q =
        T_cur_ref * (ref->features.depth[r] * ray(cs, ref->features.undistorted[r]));
    if (q.z() <= 0.0) continue;
    const Eigen::Vector2d du(cs.fx * q.x() / q.z() + cs.cx - cur.features.undistorted[c].x(),
                             cs.fy * q.y() / q.z() + cs.cy - cur.features.undistorted[c].y());
    e.push_back(du.norm() / extractor_.level_scale(cur.features.keypoints[c].octave));
  }
  return std::max(params_.min_pixel_sigma, median_of(e) / std::sqrt(2.0 * std::log(2.0)));
}

void GeometricMotionSource::test_keypoints(Work& work) {
  using Tested = Work::Tested;
  const Past& cur = work.cur;
  const Past* ref = work.ref;
  const PinholeCamera& cs = work.cs;
  const auto& pairs = work.pairs;
  const Eigen::Isometry3d& T_cur_ref = work.T_cur_ref;
  const double pixel_sigma = work.pixel_sigma;
  const double kx = work.kx;
  const double ky = work.ky;
  std::vector<Tested>& tested = work.tested;
  // 3. χ² (3 dof) of each keypoint's (Δu, Δv, Δz) with its own covariance.
  const Eigen::Matrix3d& R = T_cur_ref.linear();
  for (const auto& [c, r] : pairs) {
    if (!cur.features.has_depth(c)) continue;
    const double zr = ref->features.depth[r];
    const double zc = cur.features.depth[c];
    if (zr > params_.max_depth || zc > params_.max_depth) continue;
    const Eigen::Vector3d d = ray(cs, ref->features.undistorted[r]);
    const Eigen::Vector3d q = T_cur_ref * (zr * d);
    if (q.z() <= 0.1) continue;
    const Eigen::Vector2f& uc = cur.features.undistorted[c];
    const Eigen::Vector3d res(uc.x() - (cs.fx * q.x() / q.z() + cs.cx),
                              uc.y() - (cs.fy * q.y() / q.z() + cs.cy), zc - q.z());
    // Jacobian of the prediction (u, v, z) with respect to the reference depth.
    const Eigen::Vector3d dq = R * d;
    const Eigen::Vector3d g(cs.fx * (dq.x() * q.z() - q.x() * dq.z()) / (q.z() * q.z()),
                            cs.fy * (dq.y() * q.z() - q.y() * dq.z()) / (q.z() * q.z()), dq.z());
    const cv::Point2f& pc = cur.features.keypoints[c].pt;
    const cv::Point2f& pr = ref->features.keypoints[r].pt;
    // Keypoints on a depth discontinuity (silhouettes, T-junctions, thin structures) are not
    // fixed 3-D points: the corner slides along the occluding contour as the view changes,
    // and RGB-depth misregistration gives them either depth. They are no evidence either way.
    const double spr =
        depth_spread(ref->depth_small, cs.depth_scale, pr.x, pr.y, params_.depth_window);
    const double spc =
        depth_spread(cur.depth_small, cs.depth_scale, pc.x, pc.y, params_.depth_window);
    if (spr > edge_thr(params_, zr) || spc > edge_thr(params_, zc)) continue;
    const double szr = sigma_z(params_, zr, spr);
    const double szc = sigma_z(params_, zc, spc);
    const double sc = extractor_.level_scale(cur.features.keypoints[c].octave);
    const double sr = extractor_.level_scale(ref->features.keypoints[r].octave);
    const double spx2 = pixel_sigma * pixel_sigma * (sc * sc + sr * sr);
    Eigen::Matrix3d S = Eigen::Vector3d(spx2, spx2, szc * szc).asDiagonal();
    S += g * g.transpose() * (szr * szr);
    const double chi2 = res.dot(S.ldlt().solve(res));
    Tested t;
    t.uvz = Eigen::Vector3d((pc.x + 0.5) * kx - 0.5, (pc.y + 0.5) * ky - 0.5, zc);
    t.moving = std::isfinite(chi2) && chi2 > params_.moving_chi2;
    t.chi2 = std::isfinite(chi2) ? chi2 : 0.0;
    stats_.num_moving_keypoints += t.moving ? 1 : 0;
    tested.push_back(t);
  }
  stats_.num_tested = static_cast<int>(tested.size());
}

// 4. Candidates: HDBSCAN of the moving keypoints in (u, v, z), metric scales; compactness and
//    support tests.
void GeometricMotionSource::cluster_keypoints(const PinholeCamera& camera, Work& work) {
  using Tested = Work::Tested;
  using Candidate = Work::Candidate;
  const std::vector<Tested>& tested = work.tested;
  std::vector<Candidate>& found = work.found;
  std::vector<Eigen::Vector3d> moving;
  std::vector<std::size_t> moving_idx;  // index into tested
  for (std::size_t i = 0; i < tested.size(); ++i) {
    const Tested& t = tested[i];
    TestedKeypoint k;
    k.u = static_cast<float>(t.uvz.x());
    k.v = static_cast<float>(t.uvz.y());
    k.z = static_cast<float>(t.uvz.z());
    k.chi2 = static_cast<float>(t.chi2);
    k.moving = t.moving;
    tested_.push_back(k);
    if (!t.moving) continue;
    moving.push_back(t.uvz);
    moving_idx.push_back(i);
  }
  if (static_cast<int>(moving.size()) >= params_.min_cluster_size) {
    RowMatrixXd pts(static_cast<Eigen::Index>(moving.size()), 3);
    std::vector<double> zs;
    for (std::size_t i = 0; i < moving.size(); ++i) {
      pts.row(static_cast<Eigen::Index>(i)) = moving[i].transpose();
      zs.push_back(moving[i].z());
    }
    const double zmed = median_of(zs);
    HdbscanParams hp;
    hp.min_cluster_size = params_.min_cluster_size;
    hp.min_samples = params_.min_samples;
    const HdbscanResult h = hdbscan(pts, hp, {zmed / camera.fx, zmed / camera.fy, 1.0});
    for (int cl = 0; cl < h.num_clusters; ++cl) {
      Candidate cand;
      double u0 = 1e30, u1 = -1e30, v0 = 1e30, v1 = -1e30, z0 = 1e30, z1 = -1e30;
      for (std::size_t i = 0; i < moving.size(); ++i) {
        if (h.labels[i] != cl) continue;
        tested_[moving_idx[i]].cluster = cl;
        const Eigen::Vector3d& m = moving[i];
        cand.box.add(camera.back_project(m.x(), m.y(), m.z()));
        u0 = std::min(u0, m.x()), u1 = std::max(u1, m.x());
        v0 = std::min(v0, m.y()), v1 = std::max(v1, m.y());
        z0 = std::min(z0, m.z()), z1 = std::max(z1, m.z());
      }
      // Human-scale objects only: larger clusters are static structure under a wrong pose.
      if (cand.box.size().maxCoeff() > params_.max_object_size) continue;
      // Support: a moving object moves as a whole, so most tested keypoints in its region move;
      // false alarms on static structure are scattered among consistent keypoints.
      const double dz = 3.0 * sigma_z(params_, z1, 0.0);
      int in_region = 0;
      int moving_in_region = 0;
      for (const Tested& t : tested) {
        if (t.uvz.x() < u0 || t.uvz.x() > u1 || t.uvz.y() < v0 || t.uvz.y() > v1) continue;
        if (t.uvz.z() < z0 - dz || t.uvz.z() > z1 + dz) continue;
        ++in_region;
        moving_in_region += t.moving ? 1 : 0;
      }
      if (moving_in_region < params_.min_support * in_region) continue;
      for (std::size_t i = 0; i < moving.size(); ++i) {
        if (h.labels[i] == cl) tested_[moving_idx[i]].candidate = true;
      }
      found.push_back(std::move(cand));
    }
  }
}

// Keypoint and warp evidence of one object: merge candidates whose boxes touch (within
// box_margin) while the union stays object-sized.
void GeometricMotionSource::merge_candidates(Work& work) {
  std::vector<Work::Candidate>& found = work.found;
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t a = 0; a < found.size() && !merged; ++a) {
      for (std::size_t b = a + 1; b < found.size() && !merged; ++b) {
        if (!found[a].box.overlaps(found[b].box, params_.box_margin)) continue;
        Box3 u = found[a].box;
        u.add(found[b].box);
        if (u.size().maxCoeff() > params_.max_object_size) continue;
        found[a].box = u;
        found.erase(found.begin() + static_cast<std::ptrdiff_t>(b));
        merged = true;
      }
    }
  }
  stats_.num_candidates = static_cast<int>(found.size());
}

// 6. Confirmation over consecutive frames, and holding in the world frame.
void GeometricMotionSource::confirm_objects(std::size_t now, Work& work) {
  using Candidate = Work::Candidate;
  const Past& cur = work.cur;
  const std::vector<Candidate>& found = work.found;
  std::vector<Box3>& confirmed = work.confirmed;
  const auto world_box = [&](const Box3& b, Eigen::Matrix<double, 8, 3>* corners) {
    const Eigen::Vector3d lo = b.lo.array() - params_.box_margin;
    const Eigen::Vector3d hi = b.hi.array() + params_.box_margin;
    Box3 w;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d corner((k & 1) != 0 ? hi.x() : lo.x(), (k & 2) != 0 ? hi.y() : lo.y(),
                                   (k & 4) != 0 ? hi.z() : lo.z());
      const Eigen::Vector3d p = cur.T_world_cam * corner;
      if (corners != nullptr) corners->row(k) = p.transpose();
      w.add(p);
    }
    return w;
  };
  std::vector<Held> candidates_now;
  // GeometricMotionParams::trust_first_candidates: nothing before this frame could confirm.
  const bool first = params_.trust_first_candidates && stats_.pose_ok && !trusted_test_done_;
  if (stats_.pose_ok) trusted_test_done_ = true;
  for (const Candidate& cand : found) {
    Held obj;
    const Box3 ev = world_box(cand.box, &obj.corners_world);
    obj.lo_world = ev.lo;
    obj.hi_world = ev.hi;
    obj.last_seen = now;
    const auto confirms = [&](const Held& x) {
      Box3 xe;
      xe.lo = x.lo_world;
      xe.hi = x.hi_world;
      return ev.overlaps(xe, 0.0);
    };
    candidates_now.push_back(obj);
    if (!first && std::none_of(candidates_.begin(), candidates_.end(), confirms) &&
        std::none_of(held_.begin(), held_.end(), confirms)) {
      continue;
    }
    // A new sighting replaces the held objects it overlaps: the object moved there.
    std::erase_if(held_, [&](const Held& x) { return x.last_seen != now && confirms(x); });
    held_.push_back(obj);
    confirmed.push_back(cand.box);
    ++stats_.num_new_objects;
  }
  candidates_ = std::move(candidates_now);
  std::erase_if(held_, [&](const Held& x) {
    return now - x.last_seen > static_cast<std::size_t>(params_.hold_frames);
  });
}

// 7. Report held objects in the current camera frame; without a trusted pose their place in
//    this frame is unknown, so nothing is reported (the masker carries the last regions).
void GeometricMotionSource::report_objects(const Work& work, DynamicObjects& out) const {
  const Past& cur = work.cur;
  if (cur.pose_valid) {
    const Eigen::Isometry3d T_cam_world = cur.T_world_cam.inverse();
    for (const Held& x : held_) {
      Eigen::Matrix<float, 8, 3> c;
      for (int k = 0; k < 8; ++k) {
        c.row(k) = (T_cam_world * x.corners_world.row(k).transpose()).cast<float>().transpose();
      }
      out.boxes_3d.push_back(c);
    }
  }
}

}  // namespace ds3d::slam

namespace ds3d::detail {

// T_cur_ref refined on the inliers as a maximum a posteriori estimate: their reprojection errors
// (σ_px each) plus a Gaussian prior (σ_c [m]) that the camera centre lies at the prediction's.
// The rotation is left free. In front of a far wall a sideways shift and a rotation move the
// image alike; the matches then barely constrain the shift, and the prior settles it.
// Gauss-Newton on the left perturbation of pose_plus (monocular residuals: bf is unused).
Eigen::Isometry3d refine_towards_prediction(const std::vector<cv::Point3f>& obj,
                                            const std::vector<cv::Point2f>& img,
                                            const std::vector<int>& inliers,
                                            const PinholeCamera& camera, Eigen::Isometry3d T,
                                            const Eigen::Isometry3d& pred, double sigma_px,
                                            double sigma_c) {
  if (!(sigma_px > 0.0) || !(sigma_c > 0.0)) return T;
  const slam::StereoIntrinsics k{camera.fx, camera.fy, camera.cx, camera.cy, 40.0};
  slam::Observation o;
  o.inv_sigma2 = 1.0 / (sigma_px * sigma_px);
  const Eigen::Vector3d c_pred = pred.inverse().translation();
  for (int it = 0; it < 10; ++it) {
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    slam::Vector6d g = slam::Vector6d::Zero();
    for (const int i : inliers) {
      const auto n = static_cast<std::size_t>(i);
      o.pixel = Eigen::Vector2d(img[n].x, img[n].y);
      double r[2];
      Eigen::Matrix<double, 2, 6, Eigen::RowMajor> J;
      const Eigen::Vector3d p(obj[n].x, obj[n].y, obj[n].z);
      if (slam::reprojection_residual(k, T, p, o, r, J.data(), nullptr) == 0) continue;
      H += J.transpose() * J;
      g += J.transpose() * Eigen::Vector2d(r[0], r[1]);
    }
    // Camera centre c = −Rᵀt; under the left perturbation dc/dω = 0 and dc/dv = −Rᵀ.
    const Eigen::Vector3d rc = (T.inverse().translation() - c_pred) / sigma_c;
    const Eigen::Matrix3d Jc = -T.linear().transpose() / sigma_c;
    H.bottomRightCorner<3, 3>() += Jc.transpose() * Jc;
    g.tail<3>() += Jc.transpose() * rc;
    const slam::Vector6d delta = -H.ldlt().solve(g);
    if (!delta.allFinite()) break;
    T = slam::pose_plus(T, delta);
    if (delta.norm() < 1e-9) break;
  }
  return T;
}

}  // namespace ds3d::detail
