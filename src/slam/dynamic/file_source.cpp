// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// FileSource.
#include "ds3d/slam/dynamic/file_source.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "ds3d/errors.hpp"
#include "dynamic_impl.hpp"

namespace ds3d::slam {

void FileSourceParams::validate() const {
  DS3D_CHECK(std::isfinite(max_dt) && max_dt >= 0.0,
             "ds3d::slam::FileSourceParams: max_dt must be >= 0 (got ", max_dt, ")");
  DS3D_CHECK(std::isfinite(min_score) && min_score >= 0.0F && min_score <= 1.0F,
             "ds3d::slam::FileSourceParams: min_score must be in [0, 1] (got ", min_score, ")");
}

FileSource::FileSource(const std::filesystem::path& path, FileSourceParams params)
    : FileSource(DetectionsFile::read(path), std::move(params)) {}

FileSource::FileSource(DetectionsFile detections, FileSourceParams params)
    : file_(std::move(detections)), params_(std::move(params)) {
  params_.validate();
}

namespace {

// The frame's floor (see FileSourceParams::report_floor), when its depth image shows one.
std::optional<Eigen::Vector4f> frame_floor(const FrameInput& frame, const PinholeCamera& camera,
                                           PixelRayCache& rays) {
  if (!impl::camera_image(frame.depth, CV_16UC1, camera)) return std::nullopt;
  PreprocessParams pp;
  pp.remove_outliers = false;  // only the plane is wanted
  pp.num_threads = 1;
  const PreprocessResult pre = impl::preprocess_depth(frame, camera, pp, rays);
  const std::optional<Eigen::Vector3d> up = impl::usable_floor(pre);
  if (!up) return std::nullopt;
  return impl::floor_plane(pre, *up);
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
  const bool any_box = !out.boxes_3d.empty() || !out.boxes_2d.empty();
  if (params_.report_floor && any_box) out.support_plane = frame_floor(frame, camera, rays_);
  return out;
}

}  // namespace ds3d::slam
