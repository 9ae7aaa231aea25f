// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Step 5 of GeometricMotionSource::detect: the dense depth warp and its connected components.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "geometric_motion_impl.hpp"

namespace ds3d::slam {
namespace {

bool same_camera(const PinholeCamera& a, const PinholeCamera& b) {
  return a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.width == b.width &&
         a.height == b.height && a.k1 == b.k1 && a.k2 == b.k2 && a.p1 == b.p1 && a.p2 == b.p2 &&
         a.k3 == b.k3;
}
using detail::edge_thr;
using detail::sigma0;
using detail::sigma_z;

}  // namespace

// 5. Dense depth warp into the reference. Cell states: 0 no usable depth (missing, beyond
//    max_depth, or on a depth edge), 1 usable, 2 also tested against the reference, 3 moved in.
void GeometricMotionSource::warp_depth(const FrameInput& frame, const PinholeCamera& camera,
                                       Work& work) {
  const Past& cur = work.cur;
  const Past* ref = work.ref;
  const double pixel_sigma = work.pixel_sigma;
  const double kx = work.kx;
  const double ky = work.ky;
  const int s = work.grid.s;
  const int off = work.grid.off;
  const int gw = work.grid.gw;
  const int gh = work.grid.gh;
  std::vector<std::uint8_t>& state = work.grid.state;
  std::vector<float>& cz = work.grid.cz;
  std::vector<Eigen::Vector3f>& cp = work.grid.cp;  // camera-frame point of each usable cell
  const std::size_t nc = static_cast<std::size_t>(gw) * static_cast<std::size_t>(gh);
  if (grid_rays_.size() != nc || !same_camera(grid_camera_, camera) || grid_stride_ != s) {
    grid_rays_.resize(nc);
    for (int j = 0; j < gh; ++j) {
      for (int i = 0; i < gw; ++i) {
        const Eigen::Vector3d r = camera.back_project(off + i * s, off + j * s, 1.0);
        grid_rays_[static_cast<std::size_t>(j * gw + i)] = r.head<2>();
      }
    }
    grid_camera_ = camera;
    grid_stride_ = s;
  }
  state.assign(nc, 0);
  cz.assign(nc, 0.0F);
  cp.assign(nc, Eigen::Vector3f::Zero());
  // The warp's reference: the oldest remembered frame with a chained pose (warp_gap frames
  // back): a longer baseline than the pose's turns a walker's motion into a band of flagged
  // pixels as wide as its displacement, not a sliver at its leading edge.
  const Past* wref = ref;
  for (const Past& p : history_) {
    if (p.pose_valid) {
      wref = &p;
      break;
    }
  }
  const Eigen::Isometry3d T_ref_cur = wref->T_world_cam.inverse() * cur.T_world_cam;
  // Lateral uncertainty of the warp [full-resolution px]: the pose's σ_px per chained pose
  // step (a random walk over the steps back to the warp reference). On a slanted surface it
  // becomes a depth uncertainty of slope × σ_lat, the slope taken from the window's spread.
  std::size_t wref_age = 0;
  for (std::size_t h = 0; h < history_.size(); ++h) {
    if (&history_[h] == wref) wref_age = history_.size() - h;
  }
  const double steps = std::max(
      1.0, std::ceil(static_cast<double>(wref_age) / static_cast<double>(params_.reference_gap)));
  const double sigma_lat = pixel_sigma * std::max(kx, ky) * std::sqrt(steps);
  const double per_px = 1.0 / std::max(1, 2 * params_.warp_window);
  const double k_sigma = std::sqrt(params_.warp_chi2);
  const double ds = camera.depth_scale;
  // Largest recession of a surface between the warp's views [m]: max_speed times their time
  // apart; 0 (no recession test) when the timestamps do not give a positive interval.
  const double dt_warp = frame.timestamp - wref->timestamp;
  const double max_recede =
      std::isfinite(dt_warp) && dt_warp > 0.0 ? params_.max_speed * dt_warp : 0.0;
  for (int j = 0; j < gh; ++j) {
    const int v = off + j * s;
    const auto* drow = frame.depth.ptr<std::uint16_t>(v);
    const auto* mnrow = cur.win_min.ptr<std::uint16_t>(v);
    const auto* mxrow = cur.win_max.ptr<std::uint16_t>(v);
    for (int i = 0; i < gw; ++i) {
      const int u = off + i * s;
      if (drow[u] == 0) continue;
      const double z = drow[u] / ds;
      if (z > params_.max_depth) continue;
      const std::size_t c = static_cast<std::size_t>(j * gw + i);
      const Eigen::Vector2d& r = grid_rays_[c];
      const Eigen::Vector3d p(r.x() * z, r.y() * z, z);
      cz[c] = static_cast<float>(z);  // every cell with depth: the segments grow over edges
      cp[c] = p.cast<float>();
      if (mnrow[u] == 0 || (mxrow[u] - mnrow[u]) / ds > edge_thr(params_, z)) continue;
      state[c] = 1;
      const Eigen::Vector3d q = T_ref_cur * p;
      if (q.z() < 0.1) continue;
      const Eigen::Vector2d uv = camera.project(q);
      const auto qu = static_cast<int>(std::lround(uv.x()));
      const auto qv = static_cast<int>(std::lround(uv.y()));
      if (qu < 0 || qv < 0 || qu >= camera.width || qv >= camera.height) continue;
      const std::uint16_t rmn = wref->win_min.at<std::uint16_t>(qv, qu);
      if (rmn == 0) continue;  // missing reference depth in the window: unknown
      const double zr = rmn / ds;
      if ((wref->win_max.at<std::uint16_t>(qv, qu) - rmn) / ds > edge_thr(params_, zr)) continue;
      state[c] = 2;
      ++stats_.num_warp_tested;
      warp_tested_.emplace_back(static_cast<float>(u), static_cast<float>(v));
      // In front of every surface the reference saw around there: the space was empty.
      const double slope =
          per_px *
          std::max<double>(wref->win_max.at<std::uint16_t>(qv, qu) - rmn, mxrow[u] - mnrow[u]) / ds;
      const double sig = std::sqrt(sigma0(params_, q.z()) * sigma0(params_, q.z()) +
                                   sigma0(params_, zr) * sigma0(params_, zr) +
                                   (slope * sigma_lat) * (slope * sigma_lat));
      const double thr = std::max<double>(params_.min_depth_residual, k_sigma * sig);
      const double zr_far = wref->win_max.at<std::uint16_t>(qv, qu) / ds;
      if (zr - q.z() > thr) {
        state[c] = 3;
      } else if (max_recede > 0.0 && q.z() - zr_far > thr && q.z() - zr_far <= max_recede + thr) {
        // Behind every surface the reference saw there, by no more than an object can move
        // in the time between the views: the surface receded (a person walking away). A
        // larger step is what an occluder that moved away reveals (disocclusion): no evidence.
        state[c] = 4;
      }
      if (state[c] >= 3) {
        ++stats_.num_moving_pixels;
        moving_pixels_.emplace_back(static_cast<float>(u), static_cast<float>(v));
      }
    }
  }
}

void GeometricMotionSource::warp_candidates(const PinholeCamera& camera, Work& work) {
  using Candidate = Work::Candidate;
  const std::vector<std::uint8_t>& state = work.grid.state;
  const std::vector<float>& cz = work.grid.cz;
  const std::vector<Eigen::Vector3f>& cp = work.grid.cp;
  const int s = work.grid.s;
  const int gw = work.grid.gw;
  const int gh = work.grid.gh;
  const std::size_t nc = state.size();
  std::vector<Candidate>& found = work.found;
  // Depth-continuous connected components (8-neighbourhood) of the moved-in cells.
  const auto continuous = [&](std::size_t a, std::size_t b) {
    return std::abs(cz[a] - cz[b]) <= edge_thr(params_, std::max(cz[a], cz[b]));
  };
  std::vector<int> comp(nc, -1);
  std::vector<std::size_t> stack;
  int num_comp = 0;
  for (std::size_t c0 = 0; c0 < nc; ++c0) {
    if (state[c0] < 3 || comp[c0] >= 0) continue;
    Candidate cand;
    double area = 0;
    int i0 = gw, i1 = -1, j0 = gh, j1 = -1;
    double z0 = 1e30, z1 = -1e30;
    comp[c0] = num_comp;
    stack.assign(1, c0);
    while (!stack.empty()) {
      const std::size_t c = stack.back();
      stack.pop_back();
      const int i = static_cast<int>(c) % gw;
      const int j = static_cast<int>(c) / gw;
      cand.box.add(cp[c].cast<double>());
      const double z = cz[c];
      area += (s * z / camera.fx) * (s * z / camera.fy);
      i0 = std::min(i0, i), i1 = std::max(i1, i), j0 = std::min(j0, j), j1 = std::max(j1, j);
      z0 = std::min(z0, z), z1 = std::max(z1, z);
      // Neighbours up to two cells away: flagged bands are broken by edge and hole cells.
      for (int dj = -2; dj <= 2; ++dj) {
        for (int di = -2; di <= 2; ++di) {
          const int ii = i + di;
          const int jj = j + dj;
          if (ii < 0 || jj < 0 || ii >= gw || jj >= gh) continue;
          const auto n = static_cast<std::size_t>(jj * gw + ii);
          if (state[n] < 3 || comp[n] >= 0 || !continuous(c, n)) continue;
          comp[n] = num_comp;
          stack.push_back(n);
        }
      }
    }
    ++num_comp;
    if (area < params_.min_warp_area) continue;
    if (cand.box.size().maxCoeff() > params_.max_object_size) continue;
    // Optional support test (min_band_support > 0; off by default, see the header): at the
    // pose's own baseline (warp_gap 2) static scenes give almost no components, and the test
    // rejected most of a walker's thin leading-edge bands.
    if (params_.min_band_support > 0.0) {
      // Support, as for keypoints: most tested cells in its rectangle and depth range moved in.
      // Pose or registration errors flag scattered cells along static edges, a mover a block.
      const double dz = 3.0 * sigma_z(params_, z1, 0.0);
      int in_region = 0;
      int moved = 0;
      for (int j = j0; j <= j1; ++j) {
        for (int i = i0; i <= i1; ++i) {
          const auto c = static_cast<std::size_t>(j * gw + i);
          if (state[c] < 2 || cz[c] < z0 - dz || cz[c] > z1 + dz) continue;
          ++in_region;
          moved += state[c] >= 3 ? 1 : 0;
        }
      }
      // A mover seen against its own body (a band at its leading or trailing edge, where the
      // rest of the body in the rectangle is consistent) fails that test; its band is solid
      // though, while flags from pose errors along static edges form lines one or two cells
      // wide. So a component also passes when most tested cells of its footprint (the cells
      // within one cell of it) moved.
      int foot = 0;
      int foot_moved = 0;
      const int id = num_comp - 1;
      for (int j = std::max(0, j0 - 1); j <= std::min(gh - 1, j1 + 1); ++j) {
        for (int i = std::max(0, i0 - 1); i <= std::min(gw - 1, i1 + 1); ++i) {
          const auto c = static_cast<std::size_t>(j * gw + i);
          if (state[c] < 2) continue;
          bool near = false;
          for (int dj = -1; dj <= 1 && !near; ++dj) {
            for (int di = -1; di <= 1 && !near; ++di) {
              const int ii = i + di;
              const int jj = j + dj;
              near = ii >= 0 && jj >= 0 && ii < gw && jj < gh &&
                     comp[static_cast<std::size_t>(jj * gw + ii)] == id;
            }
          }
          if (!near) continue;
          ++foot;
          foot_moved += state[c] >= 3 ? 1 : 0;
        }
      }
      if (moved < params_.min_support * in_region && foot_moved < params_.min_band_support * foot) {
        continue;
      }
    }
    ++stats_.num_warp_candidates;
    found.push_back(std::move(cand));
  }
}

}  // namespace ds3d::slam
