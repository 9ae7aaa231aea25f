// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Private to GeometricMotionSource: its per-frame work, boxes, warp grid and depth-noise rules.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "ds3d/slam/dynamic/geometric_motion.hpp"

namespace ds3d::slam::detail {

// σ(z) = depth_noise·z² of a depth measurement [m] (Khoshelham & Elberink 2012). Inline: the
// stages in every file must round it alike.
inline double sigma0(const GeometricMotionParams& p, double z) { return p.depth_noise * z * z; }

// Depth noise of a keypoint: σ(z) inflated by half the window's depth spread, floored at
// min_depth_residual / 3.
inline double sigma_z(const GeometricMotionParams& p, double z, double spread) {
  const double s = sigma0(p, z);
  return std::max<double>(p.min_depth_residual / 3.0, std::sqrt(s * s + 0.25 * spread * spread));
}

// Largest depth spread of a continuous surface in a window: that of the noise, or of
// min_depth_residual (a slanted surface), whichever is larger.
inline double edge_thr(const GeometricMotionParams& p, double z) {
  return std::max<double>(p.min_depth_residual, 3.0 * std::sqrt(2.0) * sigma0(p, z));
}

struct Box3 {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  void add(const Eigen::Vector3d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void add(const Box3& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  [[nodiscard]] bool empty() const { return !(hi.x() >= lo.x()); }
  [[nodiscard]] Eigen::Vector3d size() const { return hi - lo; }
  [[nodiscard]] bool overlaps(const Box3& b, double margin) const {
    return (lo.array() - margin <= b.hi.array()).all() &&
           (b.lo.array() - margin <= hi.array()).all();
  }
};

// The warp grid of one frame, as GeometricMotionSource::detect builds it: cell c = j·gw + i is
// the pixel (off + i·s, off + j·s); state 0 = no usable depth (missing, too far, depth edge),
// >= 1 usable, 3 = moved into empty space; cz its depth [m] and cp its camera-frame point, set
// for every cell with depth (also edge cells, state 0). The cell vectors are empty when the
// warp did not run.
struct WarpGrid {
  std::vector<std::uint8_t> state;
  std::vector<float> cz;            // depth of every cell with depth [m], 0 = none
  std::vector<Eigen::Vector3f> cp;  // its camera-frame point
  int gw = 0, gh = 0, s = 1, off = 0;
};

struct SegmentCounts {
  int cells = 0, segments = 0, leaked = 0;
  bool ground_found = false;
};

// Object segments (step 6b of GeometricMotionSource::detect; geometric_segments.cpp).
SegmentCounts grow_segments(const GeometricMotionParams& prm, const cv::Mat& depth,
                            const PinholeCamera& camera, const Eigen::Isometry3d& T_world_cam,
                            const std::vector<Box3>& confirmed, bool carry,
                            const std::vector<TestedKeypoint>& tested,
                            const std::vector<Eigen::Vector3f>& prev_world, const WarpGrid& g,
                            cv::Mat* mask, std::vector<Eigen::Vector3f>* segment_world);

}  // namespace ds3d::slam::detail

namespace ds3d::slam {

// One frame's intermediate results, handed from stage to stage of detect().
struct GeometricMotionSource::Work {
  struct Tested {
    Eigen::Vector3d uvz;  // raw pixel (full resolution) and current depth
    bool moving = false;
    double chi2 = 0;
  };
  struct Candidate {
    detail::Box3 box;  // camera frame, of the evidence
  };
  Past cur;                   // the current frame; joins history_ at the end
  const Past* ref = nullptr;  // the pose reference, nullptr when there is none
  PinholeCamera cs{};         // camera of the source's reduced image
  double kx = 1.0;            // small → full pixel scale
  double ky = 1.0;
  std::vector<std::pair<std::size_t, std::size_t>> pairs;  // matches (current, reference)
  Eigen::Isometry3d T_cur_ref = Eigen::Isometry3d::Identity();
  // The motion prior's constant-velocity prediction of T_cur_ref (max_acceleration; none when off
  // or without a trusted motion), taken before this frame's motion is known.
  std::optional<Eigen::Isometry3d> pred;
  double pixel_sigma = 0;  // σ_px of this frame [px]
  std::vector<Tested> tested;
  std::vector<Candidate> found;
  detail::WarpGrid grid;
  std::vector<detail::Box3> confirmed;  // camera-frame evidence boxes of the objects confirmed now
};

}  // namespace ds3d::slam
