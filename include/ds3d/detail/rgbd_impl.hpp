// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of ds3d::depth_to_points (included by rgbd.hpp). Not API.

#include <cmath>
#include <type_traits>
#include <utility>

#include "ds3d/preprocess/rgbd.hpp"

namespace ds3d {

inline void DepthToPointsParams::validate() const {
  const char* fn = "ds3d::depth_to_points";
  DS3D_CHECK(stride >= 1, fn, ": stride must be >= 1 (got ", stride, ")");
  DS3D_CHECK(roi.u0 >= 0 && roi.v0 >= 0 && roi.width >= 0 && roi.height >= 0, fn,
             ": roi must have u0, v0, width, height >= 0 (got ", roi.u0, ", ", roi.v0, ", ",
             roi.width, ", ", roi.height, ")");
  DS3D_CHECK(std::isfinite(min_depth) && min_depth >= 0, fn,
             ": min_depth must be finite and >= 0 (got ", min_depth, ")");
  DS3D_CHECK(!std::isnan(max_depth) && max_depth > min_depth, fn,
             ": max_depth must be > min_depth (got ", max_depth, " <= ", min_depth, ")");
}

inline PixelRays make_pixel_rays(const PinholeCamera& camera) {
  camera.validate("ds3d::make_pixel_rays");
  PixelRays r;
  r.width = camera.width;
  r.height = camera.height;
  const auto n = static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height);
  r.x.resize(n);
  r.y.resize(n);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector2d xn =
          camera.undistort({(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy});
      const auto k = static_cast<std::size_t>(v) * static_cast<std::size_t>(camera.width) +
                     static_cast<std::size_t>(u);
      r.x[k] = xn.x();
      r.y[k] = xn.y();
    }
  }
  return r;
}

inline const PixelRays* PixelRayCache::get(const PinholeCamera& camera) {
  if (!camera.has_distortion()) return nullptr;
  const auto same = [](const PinholeCamera& a, const PinholeCamera& b) {
    return a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.width == b.width &&
           a.height == b.height && a.k1 == b.k1 && a.k2 == b.k2 && a.p1 == b.p1 && a.p2 == b.p2 &&
           a.k3 == b.k3;
  };
  if (!valid_ || !same(camera, camera_)) {
    PixelRays rays = make_pixel_rays(camera);  // throws before anything is replaced
    rays_ = std::move(rays);
    camera_ = camera;
    valid_ = true;
  }
  return &rays_;
}

namespace detail {

template <class T>
DepthToPointsResult depth_to_points_impl(const T* depth, int width, int height,
                                         std::ptrdiff_t row_stride, const PinholeCamera& camera,
                                         const DepthToPointsParams& params) {
  constexpr const char* kFn = "ds3d::depth_to_points";
  camera.validate(kFn);
  params.validate();
  DS3D_CHECK(width == camera.width && height == camera.height, kFn, ": image size ", width, "x",
             height, " does not match camera size ", camera.width, "x", camera.height);
  DS3D_CHECK(row_stride >= width, kFn, ": row_stride must be >= width (got ", row_stride, " < ",
             width, ")");
  DS3D_CHECK(depth != nullptr, kFn, ": depth is a null pointer");
  const PixelRoi& roi = params.roi;
  const int u_end = roi.width == 0 ? width : roi.u0 + roi.width;
  const int v_end = roi.height == 0 ? height : roi.v0 + roi.height;
  DS3D_CHECK(roi.u0 < width && roi.v0 < height && u_end <= width && v_end <= height, kFn, ": roi (",
             roi.u0, ", ", roi.v0, ", ", roi.width, ", ", roi.height, ") does not fit in the ",
             width, "x", height, " image");
  const bool distorted = params.undistort && camera.has_distortion();
  PixelRays local;
  const PixelRays* rays = nullptr;
  if (distorted) {
    if (params.rays != nullptr) {
      DS3D_CHECK(params.rays->width == width && params.rays->height == height &&
                     params.rays->x.size() ==
                         static_cast<std::size_t>(width) * static_cast<std::size_t>(height),
                 kFn, ": rays are for a ", params.rays->width, "x", params.rays->height,
                 " image, not ", width, "x", height);
      rays = params.rays;
    } else {
      local = make_pixel_rays(camera);
      rays = &local;
    }
  }
  // Per-column and per-row factors (u - cx) / fx and (v - cy) / fy for the undistorted case.
  std::vector<double> col(static_cast<std::size_t>(width));
  for (int u = 0; u < width; ++u) col[static_cast<std::size_t>(u)] = (u - camera.cx) / camera.fx;

  const int s = params.stride;
  const std::size_t max_points = static_cast<std::size_t>((u_end - roi.u0 + s - 1) / s) *
                                 static_cast<std::size_t>((v_end - roi.v0 + s - 1) / s);
  // Written in place (sized for every visited pixel, shrunk at the end: no zero-fill, no copy).
  DepthToPointsResult r;
  r.points.resize(static_cast<Eigen::Index>(max_points), 3);
  r.pixels.resize(static_cast<Eigen::Index>(max_points), 2);
  float* buf = r.points.data();
  std::int32_t* pix = r.pixels.data();
  std::size_t m = 0;
  const double inv_scale = 1.0 / camera.depth_scale;
  const double zmin = params.min_depth;
  const double zmax = params.max_depth;
  for (int v = roi.v0; v < v_end; v += s) {
    const T* row = depth + static_cast<std::ptrdiff_t>(v) * row_stride;
    const double fy_row = (v - camera.cy) / camera.fy;
    for (int u = roi.u0; u < u_end; u += s) {
      const T d = row[u];
      double z = 0.0;
      if constexpr (std::is_same_v<T, std::uint16_t>) {
        if (d == 0) {
          ++r.num_invalid;
          continue;
        }
        z = static_cast<double>(d) * inv_scale;
      } else {
        if (!(d > 0.0F) || !std::isfinite(d)) {
          ++r.num_invalid;
          continue;
        }
        z = static_cast<double>(d);
      }
      if (z < zmin || z > zmax) {
        ++r.num_out_of_range;
        continue;
      }
      double rx = 0;
      double ry = 0;
      if (rays != nullptr) {
        const auto k = static_cast<std::size_t>(v) * static_cast<std::size_t>(width) +
                       static_cast<std::size_t>(u);
        rx = rays->x[k];
        ry = rays->y[k];
      } else {
        rx = col[static_cast<std::size_t>(u)];
        ry = fy_row;
      }
      buf[3 * m + 0] = static_cast<float>(rx * z);
      buf[3 * m + 1] = static_cast<float>(ry * z);
      buf[3 * m + 2] = static_cast<float>(z);
      pix[2 * m + 0] = u;
      pix[2 * m + 1] = v;
      ++m;
    }
  }
  const auto rows = static_cast<Eigen::Index>(m);
  r.points.conservativeResize(rows, 3);
  r.pixels.conservativeResize(rows, 2);
  return r;
}

}  // namespace detail

inline DepthToPointsResult depth_to_points(const std::uint16_t* depth, int width, int height,
                                           std::ptrdiff_t row_stride, const PinholeCamera& camera,
                                           const DepthToPointsParams& params) {
  return detail::depth_to_points_impl(depth, width, height, row_stride, camera, params);
}

inline DepthToPointsResult depth_to_points(const float* depth, int width, int height,
                                           std::ptrdiff_t row_stride, const PinholeCamera& camera,
                                           const DepthToPointsParams& params) {
  return detail::depth_to_points_impl(depth, width, height, row_stride, camera, params);
}

namespace detail {

/// The Eigen-image overloads: checks the size fits the pointer API's int and forwards.
template <typename Image>
DepthToPointsResult depth_to_points_image(const Image& depth, const PinholeCamera& camera,
                                          const DepthToPointsParams& params) {
  DS3D_CHECK(depth.rows() <= std::numeric_limits<int>::max() &&
                 depth.cols() <= std::numeric_limits<int>::max(),
             "ds3d::depth_to_points: image too large");
  return depth_to_points_impl(depth.data(), static_cast<int>(depth.cols()),
                              static_cast<int>(depth.rows()), depth.outerStride(), camera, params);
}

}  // namespace detail

inline DepthToPointsResult depth_to_points(
    const Eigen::Ref<const DepthImageU16, 0, Eigen::OuterStride<>>& depth,
    const PinholeCamera& camera, const DepthToPointsParams& params) {
  return detail::depth_to_points_image(depth, camera, params);
}

inline DepthToPointsResult depth_to_points(
    const Eigen::Ref<const DepthImageF, 0, Eigen::OuterStride<>>& depth,
    const PinholeCamera& camera, const DepthToPointsParams& params) {
  return detail::depth_to_points_image(depth, camera, params);
}

}  // namespace ds3d
