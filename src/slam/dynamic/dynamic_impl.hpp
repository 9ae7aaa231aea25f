// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Helpers shared by the dynamic sources' .cpp files (inline: each file compiles its own copy,
// as when they were one file).
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"

namespace ds3d::slam::impl {

// True when `m` is a non-empty image of `type` and of the camera's size.
inline bool camera_image(const cv::Mat& m, int type, const PinholeCamera& camera) {
  return !m.empty() && m.type() == type && m.cols == camera.width && m.rows == camera.height;
}

// The finite rows of a point set (the KD-trees of the segmentation are built over them only).
inline std::vector<std::uint32_t> finite_rows_of(const Points3f& pts) {
  std::vector<std::uint32_t> rows;
  for (Eigen::Index r = 0; r < pts.rows(); ++r) {
    if (pts.row(r).allFinite()) rows.push_back(static_cast<std::uint32_t>(r));
  }
  return rows;
}

}  // namespace ds3d::slam::impl
