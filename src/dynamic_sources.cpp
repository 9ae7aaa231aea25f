// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/dynamic_sources.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "ds3d/errors.hpp"
#include "ds3d/geometric_motion.hpp"

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

DynamicObjects FileSource::detect(const FrameInput& frame, const PinholeCamera& /*camera*/) {
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
  return out;
}

std::vector<ImageBox> image_boxes(const DynamicObjects& objects, const PinholeCamera& camera) {
  DS3D_CHECK(objects.scores.empty() || objects.scores.size() == objects.boxes_2d.size(),
             "ds3d::slam::image_boxes: scores must be empty or one per 2-D box (got ",
             objects.scores.size(), " scores for ", objects.boxes_2d.size(), " boxes)");
  std::vector<ImageBox> out;
  for (std::size_t i = 0; i < objects.boxes_2d.size(); ++i) {
    const cv::Rect2f& r = objects.boxes_2d[i];
    ImageBox b;
    b.x_min = r.x;
    b.y_min = r.y;
    b.x_max = r.x + r.width;
    b.y_max = r.y + r.height;
    b.score = objects.scores.empty() ? 1.0F : objects.scores[i];
    // Clip to the image here so that boxes wholly outside are left out, as documented.
    b.x_max = std::min(b.x_max, static_cast<float>(camera.width) - 0.5F);
    b.y_max = std::min(b.y_max, static_cast<float>(camera.height) - 0.5F);
    b.x_min = std::max(b.x_min, -0.5F);
    b.y_min = std::max(b.y_min, -0.5F);
    if (b.x_max > b.x_min && b.y_max > b.y_min) out.push_back(b);
  }
  for (const auto& c : objects.boxes_3d) {
    if (!c.allFinite()) continue;
    if (const auto b = project_box(c, camera)) out.push_back(*b);
  }
  return out;
}

Keypoints3f keypoint_array(const OrbFeatures& features, const cv::Mat& depth,
                           const PinholeCamera& camera) {
  const bool raw = !depth.empty() && depth.type() == CV_16UC1 && depth.cols == camera.width &&
                   depth.rows == camera.height;
  Keypoints3f kp(static_cast<Eigen::Index>(features.size()), 3);
  for (std::size_t i = 0; i < features.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    const cv::Point2f& p = features.keypoints[i].pt;
    kp(r, 0) = p.x;
    kp(r, 1) = p.y;
    float z = features.depth[i];
    if (raw) {
      const int x = std::clamp(static_cast<int>(std::lround(p.x)), 0, camera.width - 1);
      const int y = std::clamp(static_cast<int>(std::lround(p.y)), 0, camera.height - 1);
      z = static_cast<float>(depth.at<std::uint16_t>(y, x) / camera.depth_scale);
    }
    kp(r, 2) = z;
  }
  return kp;
}

HdbscanMasker::HdbscanMasker(const DynamicFilterParams& params) : filter_(params) {}

std::vector<std::uint8_t> HdbscanMasker::mask(const FrameInput& frame, const PinholeCamera& camera,
                                              const OrbFeatures& features,
                                              const DynamicObjects& objects) {
  const Keypoints3f kp = keypoint_array(features, frame.depth, camera);
  last_ = filter_.filter(kp, image_boxes(objects, camera), camera);
  std::vector<std::uint8_t> out = last_.dynamic;
  const cv::Mat& m = objects.pixel_mask;
  if (!m.empty() && m.type() == CV_8UC1 && m.cols == camera.width && m.rows == camera.height) {
    for (std::size_t i = 0; i < features.size(); ++i) {
      const cv::Point2f& p = features.keypoints[i].pt;
      const int x = std::clamp(static_cast<int>(std::lround(p.x)), 0, camera.width - 1);
      const int y = std::clamp(static_cast<int>(std::lround(p.y)), 0, camera.height - 1);
      if (m.at<std::uint8_t>(y, x) != 0U) out[i] = 1;
    }
  }
  return out;
}

std::shared_ptr<DynamicObjectSource> make_dynamic_source(const std::string& spec) {
  if (spec == "none") return std::make_shared<NoDynamicObjects>();
  if (spec == "geometric") return std::make_shared<GeometricMotionSource>();
  if (spec.rfind("file:", 0) == 0) {
    const std::string path = spec.substr(5);
    DS3D_CHECK(!path.empty(), "ds3d::slam::make_dynamic_source: 'file:' needs a path (got '", spec,
               "')");
    return std::make_shared<FileSource>(path);
  }
  throw InvalidArgument(detail::concat("ds3d::slam::make_dynamic_source: unknown source '", spec,
                                       "' (expected none, geometric or file:PATH)"));
}

}  // namespace ds3d::slam
