// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// image_boxes and keypoint_array.
#include "ds3d/slam/dynamic/boxes.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "ds3d/errors.hpp"
#include "dynamic_impl.hpp"

namespace ds3d::slam {

using impl::camera_image;

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
  const auto& margins = objects.boxes_3d_margin;
  DS3D_CHECK(margins.empty() || margins.size() == objects.boxes_3d.size(),
             "ds3d::slam::image_boxes: boxes_3d_margin must be empty or one per 3-D box (got ",
             margins.size(), " margins for ", objects.boxes_3d.size(), " boxes)");
  for (std::size_t i = 0; i < margins.size(); ++i) {
    DS3D_CHECK(margins[i] >= 0.0F, "ds3d::slam::image_boxes: boxes_3d_margin[", i,
               "] must be >= 0 or +inf (got ", margins[i], ")");
  }
  for (std::size_t i = 0; i < objects.boxes_3d.size(); ++i) {
    const auto& c = objects.boxes_3d[i];
    if (!c.allFinite()) continue;
    auto b = project_box(c, camera);
    if (!b) continue;
    if (!margins.empty() && std::isfinite(margins[i])) b->solid = solid_from_corners(c, margins[i]);
    out.push_back(*b);
  }
  return out;
}

Keypoints3f keypoint_array(const OrbFeatures& features, const cv::Mat& depth,
                           const PinholeCamera& camera) {
  const bool raw = camera_image(depth, CV_16UC1, camera);
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

}  // namespace ds3d::slam
