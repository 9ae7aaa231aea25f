// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file box3.hpp
/// @brief Oriented 3-D box in the SUN RGB-D / VoteNet / 3DETR upright convention (htx spec §2).
///
/// Frame: X right, Y forward, Z up (gravity), metres. A box has its centre, full sizes
/// (dx = length along the heading arrow, dy = width across it, dz = height) and a heading `yaw`
/// in radians measured from +X towards -Y (clockwise seen from above): the length axis points
/// along (cos yaw, -sin yaw, 0). A world point p maps into the box frame by Rz(+yaw)(p - c).
/// OpenPCDet / Part-A2 use the opposite sign (yaw_OpenPCDet = -yaw).

#include <array>
#include <cmath>
#include <cstdint>

#include <Eigen/Core>

namespace ds3d {

/// One oriented box, optionally with a detection score and class label.
struct Box3 {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();  ///< box centre [m]
  Eigen::Vector3f size = Eigen::Vector3f::Zero();    ///< full sizes (dx, dy, dz) [m], > 0
  float yaw = 0.0F;         ///< heading [rad], from +X towards -Y; detector output in (-pi, pi]
  float score = 0.0F;       ///< detector score p[label] * objectness in [0, 1]; 0 for GT boxes
  float objectness = 0.0F;  ///< detector objectness 1 - p[background] in [0, 1]
  std::int32_t label = 0;   ///< class index 0..K-1
};

namespace box {

/// Point p in the frame of `b` (x along the length axis), computed in double:
/// local = Rz(+yaw)(p - centre). @note O(1).
[[nodiscard]] inline Eigen::Vector3d to_local(const Box3& b, const Eigen::Vector3d& p) {
  const double c = std::cos(static_cast<double>(b.yaw));
  const double s = std::sin(static_cast<double>(b.yaw));
  const Eigen::Vector3d d = p - b.centre.cast<double>();
  return {c * d.x() - s * d.y(), s * d.x() + c * d.y(), d.z()};
}

/// True iff p lies in `b` with every full size grown by `enlarge` metres: strict inside along
/// x and y, inclusive along z (OpenPCDet's check_pt_in_box3d rule, mirrored by the Python
/// reference ds3d.htx.boxes.points_in_box). @note O(1).
[[nodiscard]] inline bool contains(const Box3& b, const Eigen::Vector3d& p, double enlarge = 0.0) {
  const Eigen::Vector3d l = to_local(b, p);
  const Eigen::Vector3d h = (b.size.cast<double>().array() + enlarge).matrix() / 2.0;
  return std::abs(l.x()) < h.x() && std::abs(l.y()) < h.y() && std::abs(l.z()) <= h.z();
}

/// Axis-aligned hull of the 8 corners: {min, max} corners [m].
[[nodiscard]] inline std::array<Eigen::Vector3d, 2> aabb(const Box3& b) {
  const double c = std::abs(std::cos(static_cast<double>(b.yaw)));
  const double s = std::abs(std::sin(static_cast<double>(b.yaw)));
  const Eigen::Vector3d sz = b.size.cast<double>();
  const Eigen::Vector3d h((c * sz.x() + s * sz.y()) / 2.0, (s * sz.x() + c * sz.y()) / 2.0,
                          sz.z() / 2.0);
  const Eigen::Vector3d ctr = b.centre.cast<double>();
  return {ctr - h, ctr + h};
}

/// Intersection over union of the axis-aligned hulls of two boxes (0 when the union is empty).
[[nodiscard]] inline double aabb_iou(const Box3& a, const Box3& b) {
  const auto ha = aabb(a);
  const auto hb = aabb(b);
  const Eigen::Vector3d lo = ha[0].cwiseMax(hb[0]);
  const Eigen::Vector3d hi = ha[1].cwiseMin(hb[1]);
  const double inter = (hi - lo).cwiseMax(0.0).prod();
  const double uni = (ha[1] - ha[0]).prod() + (hb[1] - hb[0]).prod() - inter;
  return uni > 0.0 ? inter / uni : 0.0;
}

/// The 8 corners, centre + Rz(-yaw)(+-dx/2, +-dy/2, +-dz/2); rows 0-3 top (z+), 4-7 bottom.
[[nodiscard]] inline std::array<Eigen::Vector3d, 8> corners(const Box3& b) {
  static constexpr double kSx[8] = {1, 1, -1, -1, 1, 1, -1, -1};
  static constexpr double kSy[8] = {1, -1, -1, 1, 1, -1, -1, 1};
  static constexpr double kSz[8] = {1, 1, 1, 1, -1, -1, -1, -1};
  const double c = std::cos(static_cast<double>(b.yaw));
  const double s = std::sin(static_cast<double>(b.yaw));
  std::array<Eigen::Vector3d, 8> out;
  for (int k = 0; k < 8; ++k) {
    const double x = kSx[k] * b.size.x() / 2.0;
    const double y = kSy[k] * b.size.y() / 2.0;
    out[static_cast<std::size_t>(k)] =
        b.centre.cast<double>() +
        Eigen::Vector3d(c * x + s * y, -s * x + c * y, kSz[k] * b.size.z() / 2.0);
  }
  return out;
}

}  // namespace box
}  // namespace ds3d
