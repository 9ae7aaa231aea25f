// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// SlamFrontend::Impl, frame-to-frame odometry: the fallback when the map cannot be tracked.
#include <cmath>
#include <cstdint>
#include <vector>

#include "slam_frontend_impl.hpp"

namespace ds3d::slam {
namespace {

struct LastFrameMatches {
  std::vector<Eigen::Vector3d> world;  // the last frame's keypoint, back-projected [m]
  std::vector<std::size_t> current;    // the matched keypoint of the current frame
};

}  // namespace

// Pose of `f` from the last frame's keypoints with depth (static by the dynamic filter): each is
// back-projected with the last pose, projected with the motion prediction and matched by
// descriptor within a window (15 px × level scale, then 30), one-to-one; a pose-only
// optimisation follows. On success `f` holds the map points found around that pose (by
// projection of the last frame's map points, then the local map) and T_cw the pose.
bool SlamFrontend::Impl::track_last_frame(FrameData& f, Eigen::Isometry3d& T_cw) {
  const Eigen::Isometry3d last_wc = last_T_cw.inverse();
  const Eigen::Isometry3d pred = velocity_valid ? velocity * last_T_cw : last_T_cw;
  LastFrameMatches m;
  for (const double th : {15.0, 30.0}) {
    m = {};
    std::vector<int> taken(f.size(), 0);
    for (std::size_t j = 0; j < last.size(); ++j) {
      const double z = last.depth[j];
      if (z <= 0) continue;
      const Eigen::Vector3d pc_last((last.uv[j].x() - k.cx) * z / k.fx,
                                    (last.uv[j].y() - k.cy) * z / k.fy, z);
      const Eigen::Vector3d pw = last_wc * pc_last;
      const Eigen::Vector3d pc = pred * pw;
      if (pc.z() <= 1e-3) continue;
      const double u = k.fx * pc.x() / pc.z() + k.cx;
      const double v = k.fy * pc.y() / pc.z() + k.cy;
      const int level = last.octave[j];
      const double radius = th * scale[static_cast<std::size_t>(level)];
      int best = 256;
      int best_idx = -1;
      f.grid.for_each_in(u, v, radius, [&](int i) {
        const auto si = static_cast<std::size_t>(i);
        if (taken[si] != 0 || f.octave[si] < level - 1 || f.octave[si] > level + 1) return;
        const double du = f.uv[si].x() - u;
        const double dv = f.uv[si].y() - v;
        if (du * du + dv * dv > radius * radius) return;
        const int d = descriptor_distance(last.desc.ptr<std::uint8_t>(static_cast<int>(j)),
                                          f.desc.ptr<std::uint8_t>(i));
        if (d < best) {
          best = d;
          best_idx = i;
        }
      });
      if (best_idx < 0 || best > kThHigh) continue;
      taken[static_cast<std::size_t>(best_idx)] = 1;
      m.world.push_back(pw);
      m.current.push_back(static_cast<std::size_t>(best_idx));
    }
    if (static_cast<int>(m.world.size()) >= cfg.min_tracked_inliers) break;
  }
  if (static_cast<int>(m.world.size()) < cfg.min_tracked_inliers) return false;
  std::vector<Observation> obs;
  obs.reserve(m.current.size());
  for (const std::size_t i : m.current) obs.push_back(observation(f, i));
  const auto r = optimize_pose(k, pred, m.world, obs, cfg.pose);
  if (r.num_inliers < cfg.min_tracked_inliers || !r.T_cam_world.matrix().allFinite()) return false;
  T_cw = r.T_cam_world;
  // Map points around the odometry pose: the last frame's, then (track()) the local map's.
  std::vector<int> cand;
  for (const int pid : last.points) {
    if (pid >= 0) cand.push_back(pid);
  }
  std::fill(f.points.begin(), f.points.end(), -1);
  search_by_projection(f, T_cw, cand, 15.0, false, frame_counter);
  return true;
}

}  // namespace ds3d::slam
