// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file camera.hpp
/// @brief Pinhole RGB-D camera with Brown-Conrady distortion (OpenCV's k1 k2 p1 p2 k3 model).
///
/// Conventions: pixel (u, v) = (column, row), origin at the centre of the top-left pixel; camera
/// frame x right, y down, z forward (metres). A depth image stores z (not ray length) in units of
/// 1/depth_scale metres (TUM and Bonn: 5000 units per metre, 0 = no measurement).

#include <cmath>
#include <cstdint>

#include <Eigen/Core>

#include "ds3d/errors.hpp"

namespace ds3d {

/// Intrinsics of a pinhole camera with optional radial-tangential distortion.
struct PinholeCamera {
  double fx = 525.0;            ///< focal length along u [px], > 0
  double fy = 525.0;            ///< focal length along v [px], > 0
  double cx = 319.5;            ///< principal point u [px]
  double cy = 239.5;            ///< principal point v [px]
  int width = 640;              ///< image width [px], > 0
  int height = 480;             ///< image height [px], > 0
  double k1 = 0.0;              ///< radial distortion coefficients (OpenCV order)
  double k2 = 0.0;              ///< second radial coefficient (r⁴)
  double p1 = 0.0;              ///< tangential distortion coefficients
  double p2 = 0.0;              ///< second tangential coefficient
  double k3 = 0.0;              ///< third radial coefficient (r⁶)
  double depth_scale = 5000.0;  ///< depth-image units per metre, > 0

  /// Throws ds3d::InvalidArgument naming `function` and the bad field.
  void validate(const char* function = "ds3d::PinholeCamera") const {
    DS3D_CHECK(std::isfinite(fx) && fx > 0, function, ": fx must be finite and > 0 (got ", fx, ")");
    DS3D_CHECK(std::isfinite(fy) && fy > 0, function, ": fy must be finite and > 0 (got ", fy, ")");
    DS3D_CHECK(std::isfinite(cx), function, ": cx must be finite (got ", cx, ")");
    DS3D_CHECK(std::isfinite(cy), function, ": cy must be finite (got ", cy, ")");
    DS3D_CHECK(width > 0, function, ": width must be > 0 (got ", width, ")");
    DS3D_CHECK(height > 0, function, ": height must be > 0 (got ", height, ")");
    DS3D_CHECK(std::isfinite(k1) && std::isfinite(k2) && std::isfinite(p1) && std::isfinite(p2) &&
                   std::isfinite(k3),
               function, ": distortion coefficients must be finite");
    DS3D_CHECK(std::isfinite(depth_scale) && depth_scale > 0, function,
               ": depth_scale must be finite and > 0 (got ", depth_scale, ")");
  }

  /// True if any distortion coefficient is non-zero.
  [[nodiscard]] bool has_distortion() const {
    return k1 != 0.0 || k2 != 0.0 || p1 != 0.0 || p2 != 0.0 || k3 != 0.0;
  }

  /// Applies the distortion model to normalised image coordinates (x/z, y/z).
  [[nodiscard]] Eigen::Vector2d distort(const Eigen::Vector2d& xn) const {
    const double x = xn.x();
    const double y = xn.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
  }

  /// Inverts distort() by fixed-point iteration (as OpenCV's undistortPoints, 20 iterations).
  [[nodiscard]] Eigen::Vector2d undistort(const Eigen::Vector2d& xd) const {
    if (!has_distortion()) return xd;
    Eigen::Vector2d x = xd;
    for (int it = 0; it < 20; ++it) {
      const double r2 = x.squaredNorm();
      const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
      const Eigen::Vector2d delta(2.0 * p1 * x.x() * x.y() + p2 * (r2 + 2.0 * x.x() * x.x()),
                                  p1 * (r2 + 2.0 * x.y() * x.y()) + 2.0 * p2 * x.x() * x.y());
      x = (xd - delta) / radial;
    }
    return x;
  }

  /// Projects a camera-frame point (z > 0) to a pixel, with distortion.
  [[nodiscard]] Eigen::Vector2d project(const Eigen::Vector3d& p_cam) const {
    const Eigen::Vector2d xd = distort({p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z()});
    return {fx * xd.x() + cx, fy * xd.y() + cy};
  }

  /// Back-projects pixel (u, v) with depth z [m] to the camera frame, undistorting the pixel.
  [[nodiscard]] Eigen::Vector3d back_project(double u, double v, double z) const {
    const Eigen::Vector2d xn = undistort({(u - cx) / fx, (v - cy) / fy});
    return {xn.x() * z, xn.y() * z, z};
  }

  /// True if (u, v) lies inside the image ([0, width) × [0, height), pixel centres at integers).
  [[nodiscard]] bool in_image(double u, double v, double border = 0.0) const {
    return u >= -0.5 + border && v >= -0.5 + border && u < width - 0.5 - border &&
           v < height - 0.5 - border;
  }
};

}  // namespace ds3d
