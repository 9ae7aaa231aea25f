// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Helpers shared by the dynamic sources' .cpp files (inline: each file compiles its own copy,
// as when they were one file).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/preprocess/preprocess.hpp"
#include "ds3d/preprocess/rgbd.hpp"
#include "ds3d/slam/dynamic/objects.hpp"

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

// preprocess() on the frame's 16-bit depth image (a cloud in the camera frame) with `pp`; the
// per-pixel undistortion table comes from `rays`, built once per camera, not per frame.
inline PreprocessResult preprocess_depth(const FrameInput& frame, const PinholeCamera& camera,
                                         PreprocessParams pp, PixelRayCache& rays) {
  if (pp.depth.undistort && pp.depth.rays == nullptr) pp.depth.rays = rays.get(camera);
  return preprocess(frame.depth.ptr<std::uint16_t>(), frame.depth.cols, frame.depth.rows,
                    static_cast<std::ptrdiff_t>(frame.depth.step1()), camera, pp);
}

// The normal of the floor preprocess found (camera frame, pointing up), when it can serve as the
// floor. The preprocess prior keeps the floor normal within 30° of camera -y, so this holds;
// checked anyway so that a custom prior cannot hand a ceiling or a wall on.
inline std::optional<Eigen::Vector3d> usable_floor(const PreprocessResult& pre) {
  if (!pre.ground_found) return std::nullopt;
  const Eigen::Vector3d up = pre.ground_plane.head<3>();
  if (up.allFinite() && up.y() < 0.0 && std::isfinite(pre.ground_plane.w())) return up;
  return std::nullopt;
}

// The floor plane (n, d), n the unit normal `up` of usable_floor(pre), as the masker takes it.
inline Eigen::Vector4f floor_plane(const PreprocessResult& pre, const Eigen::Vector3d& up) {
  return (pre.ground_plane / up.norm()).cast<float>();
}

}  // namespace ds3d::slam::impl
