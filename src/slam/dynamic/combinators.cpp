// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// CompositeSource and MotionGatedSource.
#include "ds3d/slam/dynamic/combinators.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <utility>

#include <opencv2/core.hpp>

#include "ds3d/errors.hpp"
#include "ds3d/slam/dynamic/boxes.hpp"
#include "ds3d/slam/dynamic/geometric_motion.hpp"
#include "dynamic_impl.hpp"

namespace ds3d::slam {

using impl::camera_image;

namespace {

// One segmentation flag per 3-D box of `o` (0 where o gives none).
std::vector<std::uint8_t> segmented_flags(const DynamicObjects& o) {
  std::vector<std::uint8_t> f = o.segmentation.boxes_3d_segmented;
  f.resize(o.boxes_3d.size(), 0);
  return f;
}

// Appends the rows of `from` to `to`.
void append_rows(Points3f& to, const Points3f& from) {
  const Eigen::Index n = to.rows();
  to.conservativeResize(n + from.rows(), 3);
  to.bottomRows(from.rows()) = from;
}

// Sets to's segmentation flags to `flags` (one per to.boxes_3d) and adds the foreground and
// background points of `from` when one of its boxes made it into `to` segmented; empty flags
// when none is set.
void merge_segmentation(DynamicObjects& to, std::vector<std::uint8_t> flags,
                        const DynamicObjects& from, bool from_used) {
  Segmentation& t = to.segmentation;
  const Segmentation& f = from.segmentation;
  if (from_used && f.foreground_points.rows() > 0) {
    const Eigen::Index n = t.foreground_points.rows();
    t.foreground_radius =
        n == 0 ? f.foreground_radius : std::max(t.foreground_radius, f.foreground_radius);
    append_rows(t.foreground_points, f.foreground_points);
    append_rows(t.background_points, f.background_points);
    if (!t.segment_plane) t.segment_plane = f.segment_plane;
    t.segment_outside_boxes = t.segment_outside_boxes || f.segment_outside_boxes;
  }
  if (std::none_of(flags.begin(), flags.end(), [](std::uint8_t x) { return x != 0U; })) {
    flags.clear();
  }
  t.boxes_3d_segmented = std::move(flags);
}

}  // namespace

CompositeSource::CompositeSource(std::shared_ptr<DynamicObjectSource> first,
                                 std::shared_ptr<DynamicObjectSource> second)
    : first_(std::move(first)), second_(std::move(second)) {
  DS3D_CHECK(first_ != nullptr && second_ != nullptr,
             "ds3d::slam::CompositeSource: both sources must be non-null (got first ",
             first_ ? "set" : "null", ", second ", second_ ? "set" : "null", ")");
}

std::string CompositeSource::name() const { return first_->name() + "+" + second_->name(); }

bool CompositeSource::uses_orb_corners() const {
  return first_->uses_orb_corners() || second_->uses_orb_corners();
}

namespace {

// What the two sources of a combinator prepared (either may be null).
struct PreparedPair final : PreparedDetection {
  std::shared_ptr<const PreparedDetection> first, second;
};

const PreparedDetection* first_of(const PreparedDetection* p) {
  const auto* pair = dynamic_cast<const PreparedPair*>(p);
  return pair != nullptr ? pair->first.get() : nullptr;
}

const PreparedDetection* second_of(const PreparedDetection* p) {
  const auto* pair = dynamic_cast<const PreparedPair*>(p);
  return pair != nullptr ? pair->second.get() : nullptr;
}

std::shared_ptr<const PreparedDetection> pair_of(std::shared_ptr<const PreparedDetection> first,
                                                 std::shared_ptr<const PreparedDetection> second) {
  if (first == nullptr && second == nullptr) return nullptr;
  auto p = std::make_shared<PreparedPair>();
  p->first = std::move(first);
  p->second = std::move(second);
  return p;
}

}  // namespace

std::shared_ptr<const PreparedDetection> CompositeSource::prepare(
    const FrameInput& frame, const PinholeCamera& camera) const {
  return pair_of(first_->prepare(frame, camera), nullptr);
}

DynamicObjects CompositeSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  return detect_prepared(frame, camera, nullptr);
}

DynamicObjects CompositeSource::detect_prepared(const FrameInput& frame,
                                                const PinholeCamera& camera,
                                                const PreparedDetection* prepared) {
  DynamicObjects out = first_->detect_prepared(frame, camera, first_of(prepared));
  // The second source sees the whole frame: a motion source needs the static background inside
  // the first one's boxes for its own ego-motion, and must see what the first one missed or
  // boxed too small (docs/dynamic.md, "Combining sources").
  DynamicObjects more = second_->detect(frame, camera);
  if (out.scores.empty() && !more.scores.empty()) out.scores.assign(out.boxes_2d.size(), 1.0F);
  if (!out.scores.empty() && more.scores.empty()) more.scores.assign(more.boxes_2d.size(), 1.0F);
  out.boxes_2d.insert(out.boxes_2d.end(), more.boxes_2d.begin(), more.boxes_2d.end());
  out.scores.insert(out.scores.end(), more.scores.begin(), more.scores.end());
  if (!out.boxes_3d_margin.empty() || !more.boxes_3d_margin.empty()) {
    // One margin per 3-D box once either source gives them (+inf: rectangle and depth range).
    constexpr float kInf = std::numeric_limits<float>::infinity();
    out.boxes_3d_margin.resize(out.boxes_3d.size(), kInf);
    more.boxes_3d_margin.resize(more.boxes_3d.size(), kInf);
    out.boxes_3d_margin.insert(out.boxes_3d_margin.end(), more.boxes_3d_margin.begin(),
                               more.boxes_3d_margin.end());
  }
  std::vector<std::uint8_t> flags = segmented_flags(out);
  const std::vector<std::uint8_t> more_flags = segmented_flags(more);
  flags.insert(flags.end(), more_flags.begin(), more_flags.end());
  out.boxes_3d.insert(out.boxes_3d.end(), more.boxes_3d.begin(), more.boxes_3d.end());
  merge_segmentation(out, std::move(flags), more, true);
  if (!out.support_plane) out.support_plane = more.support_plane;
  if (!out.ego_motion) out.ego_motion = more.ego_motion;
  if (out.pixel_mask.empty()) {
    out.pixel_mask = more.pixel_mask;
  } else if (!more.pixel_mask.empty() && more.pixel_mask.size() == out.pixel_mask.size() &&
             more.pixel_mask.type() == out.pixel_mask.type()) {
    cv::bitwise_or(out.pixel_mask, more.pixel_mask, out.pixel_mask);
  }
  return out;
}

// ---- MotionGatedSource -------------------------------------------------------------------------

void MotionGateParams::validate() const {
  DS3D_CHECK(std::isfinite(keypoint_chi2) && keypoint_chi2 > 0.0,
             "ds3d::slam::MotionGateParams: keypoint_chi2 must be > 0 (got ", keypoint_chi2, ")");
  DS3D_CHECK(std::isfinite(alpha) && alpha > 0.0 && alpha < 1.0,
             "ds3d::slam::MotionGateParams: alpha must be in (0, 1) (got ", alpha, ")");
  DS3D_CHECK(hold_frames >= 0, "ds3d::slam::MotionGateParams: hold_frames must be >= 0 (got ",
             hold_frames, ")");
  DS3D_CHECK(std::isfinite(max_speed) && max_speed >= 0.0,
             "ds3d::slam::MotionGateParams: max_speed must be >= 0 (got ", max_speed, ")");
}

MotionGatedSource::MotionGatedSource(std::shared_ptr<DynamicObjectSource> semantic,
                                     std::shared_ptr<DynamicObjectSource> motion,
                                     MotionGateParams params)
    : semantic_(std::move(semantic)), motion_(std::move(motion)), params_(params) {
  DS3D_CHECK(semantic_ != nullptr && motion_ != nullptr,
             "ds3d::slam::MotionGatedSource: both sources must be non-null (got semantic ",
             semantic_ ? "set" : "null", ", motion ", motion_ ? "set" : "null", ")");
  params_.validate();
}

std::string MotionGatedSource::name() const {
  return semantic_->name() + (params_.evidence ? "&&" : "&") + motion_->name();
}

bool MotionGatedSource::uses_orb_corners() const {
  return semantic_->uses_orb_corners() || motion_->uses_orb_corners();
}

namespace {

// P(X >= k) for X ~ Binomial(n, p), summed in log space from k up until the terms vanish.
double binomial_sf(std::size_t k, std::size_t n, double p) {
  if (k == 0) return 1.0;
  if (k > n) return 0.0;
  if (p <= 0.0) return 0.0;
  if (p >= 1.0) return 1.0;
  const double dn = static_cast<double>(n);
  const double lp = std::log(p);
  const double lq = std::log1p(-p);
  double sum = 0.0;
  for (std::size_t i = k; i <= n; ++i) {
    const double di = static_cast<double>(i);
    const double term = std::exp(std::lgamma(dn + 1.0) - std::lgamma(di + 1.0) -
                                 std::lgamma(dn - di + 1.0) + di * lp + (dn - di) * lq);
    sum += term;
    if (di > dn * p && term < 1e-17 * sum) break;  // past the mode, the rest is negligible
  }
  return std::min(1.0, sum);
}

// Whether pixel (u, v) with depth z lies in box `b`, close to how the masker gates it: inside its
// solid (grown by its margin and 3σ(z)) when it has one, else inside its rectangle and depth range
// ± 3σ(z). Unlike the masker (DynamicFeatureFilter), σ is taken at the point's depth rather than
// at the range's ends, and with a solid only a looser depth bound precedes the solid test (the
// masker also requires the depth range ± 3σ there).
// `p` is the pixel back-projected (camera frame), computed at most once per point by the caller.
bool in_box(const ImageBox& b, const PinholeCamera& camera, float u, float v, float z,
            float depth_noise, std::optional<Eigen::Vector3f>& p) {
  if (!b.contains(u, v) || !(z > 0.0F)) return false;
  const float sigma_z = depth_noise * z * z;
  if (b.solid) {
    // Quick reject by depth first: the grown solid reaches at most √3·(margin + 3σ(z)·|ray|)
    // beyond the corners' depth range (|ray| < 2 inside any real field of view).
    const float reach = std::sqrt(3.0F) * (b.solid->margin + 6.0F * sigma_z);
    if (b.has_depth_range() && (z < b.z_min - reach || z > b.z_max + reach)) return false;
    if (!p) p = camera.back_project(u, v, z).cast<float>();
    const Eigen::Vector3f ray(p->x() / z, p->y() / z, 1.0F);
    return b.solid->contains(*p, ray, sigma_z);
  }
  if (!b.has_depth_range()) return true;
  return z >= b.z_min - 3.0F * sigma_z && z <= b.z_max + 3.0F * sigma_z;
}

// The semantic boxes as image boxes (2-D first, then 3-D; an empty optional when wholly outside
// the image or behind the camera).
std::vector<std::optional<ImageBox>> semantic_image_boxes(const DynamicObjects& sem,
                                                          const PinholeCamera& camera) {
  std::vector<std::optional<ImageBox>> boxes;
  for (const cv::Rect2f& r : sem.boxes_2d) {
    DynamicObjects one;
    one.boxes_2d.push_back(r);
    const std::vector<ImageBox> ib = image_boxes(one, camera);
    boxes.push_back(ib.empty() ? std::nullopt : std::optional<ImageBox>(ib.front()));
  }
  for (std::size_t i = 0; i < sem.boxes_3d.size(); ++i) {
    DynamicObjects one;
    one.boxes_3d.push_back(sem.boxes_3d[i]);
    if (!sem.boxes_3d_margin.empty()) one.boxes_3d_margin.push_back(sem.boxes_3d_margin[i]);
    const std::vector<ImageBox> ib = image_boxes(one, camera);
    boxes.push_back(ib.empty() ? std::nullopt : std::optional<ImageBox>(ib.front()));
  }
  return boxes;
}

// The evidence gate's test in this frame, one flag per semantic box of `boxes` (2-D boxes: 0):
// the geometric source's raw evidence inside the box is significantly above its false-alarm
// rate outside every semantic box (see MotionGatedSource).
std::vector<std::uint8_t> box_evidence(const FrameInput& frame, const PinholeCamera& camera,
                                       const GeometricMotionSource* geo, const DynamicObjects& sem,
                                       const std::vector<std::optional<ImageBox>>& boxes,
                                       const MotionGateParams& params) {
  const float noise = geo->params().depth_noise;
  const bool raw_depth = camera_image(frame.depth, CV_16UC1, camera);
  const auto depth_at = [&](float u, float v) {
    if (!raw_depth) return 0.0F;
    const int x = std::clamp(static_cast<int>(std::lround(u)), 0, camera.width - 1);
    const int y = std::clamp(static_cast<int>(std::lround(v)), 0, camera.height - 1);
    return static_cast<float>(frame.depth.at<std::uint16_t>(y, x) / camera.depth_scale);
  };
  // Trials and hits per box (index boxes.size() = outside every box: the frame's rate).
  const std::size_t nb = boxes.size();
  std::vector<std::size_t> kp_n(nb + 1, 0), kp_k(nb + 1, 0), px_n(nb + 1, 0), px_k(nb + 1, 0);
  const auto count = [&](float u, float v, float z, bool hit, std::vector<std::size_t>& n,
                         std::vector<std::size_t>& k) {
    bool inside = false;
    std::optional<Eigen::Vector3f> p;  // back-projected once (undistortion iterates)
    for (std::size_t i = 0; i < nb; ++i) {
      if (!boxes[i] || !in_box(*boxes[i], camera, u, v, z, noise, p)) continue;
      inside = true;
      ++n[i];
      k[i] += hit ? 1U : 0U;
    }
    if (!inside) {
      ++n[nb];
      k[nb] += hit ? 1U : 0U;
    }
  };
  for (const TestedKeypoint& t : geo->last_tested()) {
    count(t.u, t.v, t.z, static_cast<double>(t.chi2) > params.keypoint_chi2, kp_n, kp_k);
  }
  if (params.pixel_evidence) {
    // Flagged pixels are a subset of the tested ones (the same grid positions, in order).
    std::vector<std::int64_t> flagged;
    flagged.reserve(geo->last_moving_pixels().size());
    const auto key = [&](const Eigen::Vector2f& q) {
      return static_cast<std::int64_t>(std::lround(q.y())) * camera.width +
             static_cast<std::int64_t>(std::lround(q.x()));
    };
    for (const Eigen::Vector2f& q : geo->last_moving_pixels()) flagged.push_back(key(q));
    std::sort(flagged.begin(), flagged.end());
    for (const Eigen::Vector2f& q : geo->last_warp_tested()) {
      const bool hit = std::binary_search(flagged.begin(), flagged.end(), key(q));
      count(q.x(), q.y(), depth_at(q.x(), q.y()), hit, px_n, px_k);
    }
  }
  // The frame's false-alarm rate outside the boxes (pose error, sensor noise), never below the
  // nominal level of the per-point test; (k + 1) / (n + 2) so that few trials stay cautious.
  const auto rate = [](std::size_t k, std::size_t n, double nominal) {
    return std::max(nominal, (static_cast<double>(k) + 1.0) / (static_cast<double>(n) + 2.0));
  };
  // χ²₃ upper tail at keypoint_chi2 (closed form for 3 dof).
  const double c = params.keypoint_chi2;
  const double kp_nominal =
      std::erfc(std::sqrt(c / 2.0)) + std::sqrt(2.0 * c / std::numbers::pi) * std::exp(-c / 2.0);
  // The warp's per-pixel test: χ²₁ at warp_chi2.
  const double px_nominal = std::erfc(std::sqrt(geo->params().warp_chi2 / 2.0));
  const double kp_p0 = rate(kp_k[nb], kp_n[nb], kp_nominal);
  const double px_p0 = rate(px_k[nb], px_n[nb], px_nominal);
  // Evidence of this frame per box. 2-D boxes have no world position to track, and evidence in
  // one frame alone is not enough (below): they keep the overlap gate.
  std::vector<std::uint8_t> evidence(nb, 0);
  for (std::size_t i = sem.boxes_2d.size(); i < nb; ++i) {
    if (!boxes[i]) continue;
    const bool kp_ok = binomial_sf(kp_k[i], kp_n[i], kp_p0) < params.alpha;
    const bool px_ok = params.pixel_evidence && binomial_sf(px_k[i], px_n[i], px_p0) < params.alpha;
    evidence[i] = kp_ok || px_ok ? 1 : 0;
  }
  return evidence;
}

// Appends the kept semantic boxes (`keep`, one per 2-D then 3-D box of `sem`) to `out`, with
// their scores, margins and segmentation; returns how many.
std::size_t add_kept_boxes(DynamicObjects& out, const DynamicObjects& sem,
                           const std::vector<std::uint8_t>& keep) {
  std::size_t kept = 0;
  // Scores: one per 2-D box when either source gives them (1 for boxes without).
  const bool with_scores = !sem.scores.empty() || !out.scores.empty();
  if (with_scores && out.scores.empty()) out.scores.assign(out.boxes_2d.size(), 1.0F);
  for (std::size_t i = 0; i < sem.boxes_2d.size(); ++i) {
    if (keep[i] == 0) continue;
    out.boxes_2d.push_back(sem.boxes_2d[i]);
    if (with_scores) out.scores.push_back(sem.scores.empty() ? 1.0F : sem.scores[i]);
    ++kept;
  }
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const bool with_margins = !sem.boxes_3d_margin.empty() || !out.boxes_3d_margin.empty();
  if (with_margins) out.boxes_3d_margin.resize(out.boxes_3d.size(), kInf);
  std::vector<std::uint8_t> flags = segmented_flags(out);
  const std::vector<std::uint8_t> sem_flags = segmented_flags(sem);
  bool sem_segmented = false;
  for (std::size_t j = 0; j < sem.boxes_3d.size(); ++j) {
    if (keep[sem.boxes_2d.size() + j] == 0) continue;
    out.boxes_3d.push_back(sem.boxes_3d[j]);
    flags.push_back(sem_flags[j]);
    sem_segmented = sem_segmented || sem_flags[j] != 0U;
    if (with_margins) {
      out.boxes_3d_margin.push_back(sem.boxes_3d_margin.empty() ? kInf : sem.boxes_3d_margin[j]);
    }
    ++kept;
  }
  merge_segmentation(out, std::move(flags), sem, sem_segmented);
  return kept;
}

}  // namespace

std::shared_ptr<const PreparedDetection> MotionGatedSource::prepare(
    const FrameInput& frame, const PinholeCamera& camera) const {
  return pair_of(semantic_->prepare(frame, camera), motion_->prepare(frame, camera));
}

DynamicObjects MotionGatedSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  return detect_prepared(frame, camera, nullptr);
}

DynamicObjects MotionGatedSource::detect_prepared(const FrameInput& frame,
                                                  const PinholeCamera& camera,
                                                  const PreparedDetection* prepared) {
  const DynamicObjects sem = semantic_->detect_prepared(frame, camera, first_of(prepared));
  DynamicObjects out = motion_->detect_prepared(frame, camera, second_of(prepared));
  ++frame_count_;
  const std::size_t now = frame_count_;
  const std::vector<ImageBox> moving = image_boxes(out, camera);
  const cv::Mat& m = out.pixel_mask;
  const bool has_mask = camera_image(m, CV_8UC1, camera);
  const cv::Rect image(0, 0, camera.width, camera.height);
  // One semantic box (as the image box image_boxes() makes of it) against the motion evidence.
  const auto gate = [&](const ImageBox& b) {
    for (const ImageBox& q : moving) {
      if (b.x_max < q.x_min || q.x_max < b.x_min || b.y_max < q.y_min || q.y_max < b.y_min) {
        continue;
      }
      if (b.has_depth_range() && q.has_depth_range() && (b.z_max < q.z_min || q.z_max < b.z_min)) {
        continue;
      }
      return true;
    }
    if (!has_mask) return false;
    const cv::Rect r(
        cv::Point(static_cast<int>(std::floor(b.x_min)), static_cast<int>(std::floor(b.y_min))),
        cv::Point(static_cast<int>(std::ceil(b.x_max)) + 1,
                  static_cast<int>(std::ceil(b.y_max)) + 1));
    const cv::Rect ri = r & image;
    return ri.area() > 0 && cv::countNonZero(m(ri)) > 0;
  };
  last_semantic_ = sem.boxes_2d.size() + sem.boxes_3d.size();
  last_kept_ = 0;
  last_by_evidence_ = 0;
  last_by_track_ = 0;

  const std::vector<std::optional<ImageBox>> boxes = semantic_image_boxes(sem, camera);
  std::vector<std::uint8_t> keep(boxes.size(), 0);
  for (std::size_t i = 0; i < boxes.size(); ++i) keep[i] = boxes[i] && gate(*boxes[i]) ? 1 : 0;

  const auto* geo = dynamic_cast<const GeometricMotionSource*>(motion_.get());
  if (params_.evidence && geo != nullptr && !boxes.empty()) {
    const std::vector<std::uint8_t> evidence =
        box_evidence(frame, camera, geo, sem, boxes, params_);
    track_boxes(frame.timestamp, now, sem, boxes, evidence, geo->last_stats().T_world_cam, keep);
  }
  last_kept_ = add_kept_boxes(out, sem, keep);
  // Under the gate the segmentation decides inside the confirmed boxes only: outside them the
  // part head's foreground has no motion evidence (a seated person who does not move).
  out.segmentation.segment_outside_boxes = false;
  // The semantic source's floor (the motion source usually has none to give); with
  // report_floor also the floor the semantic source's segmentation left out.
  if (sem.support_plane) {
    out.support_plane = sem.support_plane;
  } else if (params_.report_floor && sem.segmentation.segment_plane) {
    out.support_plane = sem.segmentation.segment_plane;
  }
  return out;
}

void MotionGatedSource::track_boxes(double timestamp, std::size_t now, const DynamicObjects& sem,
                                    const std::vector<std::optional<ImageBox>>& boxes,
                                    const std::vector<std::uint8_t>& evidence,
                                    const Eigen::Isometry3d& T_world_cam,
                                    std::vector<std::uint8_t>& keep) {
  const std::size_t n2 = sem.boxes_2d.size();
  // Tracks of 3-D boxes (world frame): evidence in two consecutive frames confirms a track (the
  // geometric source's rule for its candidates), a motion object overlapping the box at once;
  // a confirmed track keeps every box associated with it until hold_frames frames pass without
  // evidence, as the geometric source holds its objects.
  std::erase_if(tracks_, [&](const Track& t) {
    return now - t.last_evidence > static_cast<std::size_t>(params_.hold_frames);
  });
  std::vector<std::uint8_t> used(tracks_.size(), 0);
  for (std::size_t j = 0; j < sem.boxes_3d.size(); ++j) {
    const std::size_t i = n2 + j;
    if (!boxes[i]) continue;
    const Eigen::Matrix<float, 8, 3>& c3 = sem.boxes_3d[j];
    const Eigen::Vector3d centre = T_world_cam * c3.cast<double>().colwise().mean().transpose();
    const float margin = sem.boxes_3d_margin.empty() ? std::numeric_limits<float>::infinity()
                                                     : sem.boxes_3d_margin[j];
    // Two sightings of one object: their centres differ by up to 3σ of a difference of two
    // uncertain centres, plus what it can move in between. Without a finite uncertainty, half
    // the box's diagonal.
    const double half_diag =
        0.5 * static_cast<double>((c3.colwise().maxCoeff() - c3.colwise().minCoeff()).norm());
    const double reach =
        std::isfinite(margin) ? 3.0 * std::sqrt(2.0) * static_cast<double>(margin) : half_diag;
    std::size_t best = tracks_.size();
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t t = 0; t < tracks_.size(); ++t) {
      if (used[t] != 0) continue;
      const double dt = std::max(0.0, timestamp - tracks_[t].timestamp);
      const double d = (centre - tracks_[t].centre_world).norm();
      if (d <= reach + params_.max_speed * dt && d < best_d) {
        best = t;
        best_d = d;
      }
    }
    const bool old = keep[i] != 0;
    const bool ev = old || evidence[i] != 0;
    if (best == tracks_.size()) {
      if (!ev) continue;
      tracks_.push_back(Track{centre, timestamp, now, old});
      used.push_back(1);
      continue;
    }
    Track& t = tracks_[best];
    used[best] = 1;
    if (ev) {
      t.confirmed = t.confirmed || old || t.last_evidence + 1 == now;
      t.last_evidence = now;
    }
    t.centre_world = centre;
    t.timestamp = timestamp;
    if (!old && t.confirmed) {
      keep[i] = 1;
      ++(evidence[i] != 0 ? last_by_evidence_ : last_by_track_);
    }
  }
}

}  // namespace ds3d::slam
