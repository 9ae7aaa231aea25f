// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// FileSource.
#include "ds3d/slam/dynamic/file_source.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>
#include <vector>

#include "ds3d/errors.hpp"
#include "dynamic_impl.hpp"

namespace ds3d::slam {

void FileSourceParams::validate() const {
  DS3D_CHECK(std::isfinite(max_dt) && max_dt >= 0.0,
             "ds3d::slam::FileSourceParams: max_dt must be >= 0 (got ", max_dt, ")");
  DS3D_CHECK(std::isfinite(min_score) && min_score >= 0.0F && min_score <= 1.0F,
             "ds3d::slam::FileSourceParams: min_score must be in [0, 1] (got ", min_score, ")");
  DS3D_CHECK(hold_frames >= 0, "ds3d::slam::FileSourceParams: hold_frames must be >= 0 (got ",
             hold_frames, ")");
  DS3D_CHECK(hold_min_points >= 1,
             "ds3d::slam::FileSourceParams: hold_min_points must be >= 1 (got ", hold_min_points,
             ")");
  DS3D_CHECK(std::isfinite(hold_margin) && hold_margin >= 0.0F,
             "ds3d::slam::FileSourceParams: hold_margin must be finite and >= 0 (got ", hold_margin,
             ")");
  DS3D_CHECK(std::isfinite(hold_seconds) && hold_seconds >= 0.0,
             "ds3d::slam::FileSourceParams: hold_seconds must be finite and >= 0 (got ",
             hold_seconds, ")");
}

FileSource::FileSource(const std::filesystem::path& path, FileSourceParams params)
    : FileSource(DetectionsFile::read(path), std::move(params)) {}

FileSource::FileSource(DetectionsFile detections, FileSourceParams params)
    : file_(std::move(detections)), params_(std::move(params)) {
  params_.validate();
}

namespace {

// The frame's cloud (voxel centroids, the floor removed) and floor, when it has a depth image.
std::optional<PreprocessResult> frame_cloud(const FrameInput& frame, const PinholeCamera& camera,
                                            PixelRayCache& rays) {
  if (!impl::camera_image(frame.depth, CV_16UC1, camera)) return std::nullopt;
  PreprocessParams pp;
  pp.remove_outliers = false;  // the plane and the centroids are wanted, not a detector input
  pp.num_threads = 1;
  return impl::preprocess_depth(frame, camera, pp, rays);
}

// The floor (see FileSourceParams::report_floor) of a frame's cloud, when it shows one.
std::optional<Eigen::Vector4f> cloud_floor(const PreprocessResult& pre) {
  const std::optional<Eigen::Vector3d> up = impl::usable_floor(pre);
  if (!up) return std::nullopt;
  return impl::floor_plane(pre, *up);
}

// Centroid and count of the finite points with z > 0 inside `solid` (grown by its margin).
std::pair<Eigen::Vector3f, int> points_in(const SolidBox& solid, const Points3f& points) {
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  int n = 0;
  for (Eigen::Index r = 0; r < points.rows(); ++r) {
    const Eigen::Vector3f p = points.row(r).transpose();
    if (!p.allFinite() || !(p.z() > 0.0F) || !solid.contains(p, p / p.z(), 0.0F)) continue;
    sum += p;
    ++n;
  }
  return {n > 0 ? Eigen::Vector3f(sum / static_cast<float>(n)) : Eigen::Vector3f::Zero(), n};
}

// Whether a box of this frame with solid `b` continues the held `h`: their centres lie within
// the held box's largest half size (the detector reported the object again about there).
bool continues(const SolidBox& h, const SolidBox& b) {
  return (b.centre - h.centre).norm() < h.half.maxCoeff();
}

}  // namespace

DynamicObjects FileSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  DynamicObjects out;
  const DetectionFrame* f = file_.find(frame.timestamp, params_.max_dt);
  if (f == nullptr) {
    ++unmatched_;
    return out;
  }
  ++matched_;
  for (const Detection& d : f->detections) {
    if (d.score < params_.min_score) continue;
    if (!params_.classes.empty() &&
        std::find(params_.classes.begin(), params_.classes.end(), d.cls) == params_.classes.end()) {
      continue;
    }
    if (d.is_3d) {
      out.boxes_3d.push_back(d.corners);
    } else {
      out.boxes_2d.emplace_back(d.box.x_min, d.box.y_min, d.box.width(), d.box.height());
      out.scores.push_back(d.score);
    }
  }
  const bool hold_on = params_.hold_frames > 0;
  std::optional<PreprocessResult> pre;
  if ((params_.report_floor && (!out.boxes_3d.empty() || !out.boxes_2d.empty())) ||
      (hold_on && (!out.boxes_3d.empty() || !held_.empty()))) {
    pre = frame_cloud(frame, camera, rays_);
  }
  if (hold_on) hold(frame, pre ? &pre->points : nullptr, out);
  const bool any_box = !out.boxes_3d.empty() || !out.boxes_2d.empty();
  if (params_.report_floor && any_box && pre) out.support_plane = cloud_floor(*pre);
  return out;
}

// FileSourceParams::hold_frames: carries the held boxes that no box of this frame continues while
// enough points remain in them, then holds this frame's 3-D boxes. Without a cloud nothing is
// carried and nothing held.
void FileSource::hold(const FrameInput& frame, const Points3f* points, DynamicObjects& out) {
  if (points == nullptr) {
    held_.clear();
    return;
  }
  std::vector<HeldBox> next;
  std::vector<SolidBox> solids;
  for (const auto& c : out.boxes_3d) {
    std::optional<SolidBox> s = solid_from_corners(c, params_.hold_margin);
    if (!s) continue;
    const auto [centroid, n] = points_in(*s, *points);
    solids.push_back(*s);
    if (n >= params_.hold_min_points) {
      next.push_back({c, *s, Eigen::Vector3f(centroid - s->centre), frame.timestamp, 0});
    }
  }
  for (HeldBox h : held_) {
    const double dt = frame.timestamp - h.timestamp;
    if (h.age >= params_.hold_frames || !(dt >= 0.0 && dt <= params_.hold_seconds)) continue;
    if (std::any_of(solids.begin(), solids.end(),
                    [&](const SolidBox& b) { return continues(h.solid, b); })) {
      continue;
    }
    int n = 0;
    for (int step = 0; step < 2; ++step) {  // mean shift: the box follows its points
      const auto [centroid, count] = points_in(h.solid, *points);
      n = count;
      if (n < params_.hold_min_points) break;
      const Eigen::Vector3f move = centroid - h.offset - h.solid.centre;
      h.solid.centre += move;
      h.corners.rowwise() += move.transpose();
    }
    if (n < params_.hold_min_points) continue;
    ++h.age;
    out.boxes_3d.push_back(h.corners);
    ++carried_;
    next.push_back(h);
  }
  held_ = std::move(next);
}

}  // namespace ds3d::slam
