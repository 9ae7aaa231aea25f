// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Step 6b of GeometricMotionSource::detect: object segments grown over the warp grid.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "ds3d/preprocess/preprocess.hpp"
#include "ds3d/preprocess/ransac_plane.hpp"
#include "geometric_motion_impl.hpp"

namespace ds3d::slam::detail {
namespace {

// The floor under the segments, when one is found (see find_floor).
struct Floor {
  std::vector<std::uint8_t> ground;                 // 1 = the cell lies on the floor
  Eigen::Vector4d plane = Eigen::Vector4d::Zero();  // (n, d), n the unit up vector, when found
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX();    // horizontal axes of the floor, when found
  Eigen::Vector3d e2 = Eigen::Vector3d::UnitZ();
};

// Seeds of the segments: 0 = not a seed, 1 = evidence of this frame, 2 = carried from the last
// frame's segment.
std::vector<std::uint8_t> seed_cells(const GeometricMotionParams& prm, const PinholeCamera& camera,
                                     const Eigen::Isometry3d& T_world_cam,
                                     const std::vector<Box3>& confirmed, bool carry,
                                     const std::vector<TestedKeypoint>& tested,
                                     const std::vector<Eigen::Vector3f>& prev_world,
                                     const WarpGrid& g) {
  const std::size_t nc = g.state.size();
  const auto cell_of = [&](double u, double v) -> std::ptrdiff_t {
    const auto i = static_cast<int>(std::lround((u - g.off) / g.s));
    const auto j = static_cast<int>(std::lround((v - g.off) / g.s));
    if (i < 0 || j < 0 || i >= g.gw || j >= g.gh) return -1;
    return static_cast<std::ptrdiff_t>(j) * g.gw + i;
  };
  // Depth and point of every grid cell with depth (edges included: the region growing's own
  // continuity test separates objects from what lies behind them), 0 = none.
  const std::vector<float>& zall = g.cz;
  const std::vector<Eigen::Vector3f>& pall = g.cp;
  // 0 = not a seed, 1 = evidence of this frame, 2 = carried from the last frame's segment.
  std::vector<std::uint8_t> seed(nc, 0);
  const double m = prm.box_margin;
  const auto in_confirmed = [&](const Eigen::Vector3f& p) {
    return std::any_of(confirmed.begin(), confirmed.end(), [&](const Box3& b) {
      return (p.cast<double>().array() >= b.lo.array() - m).all() &&
             (p.cast<double>().array() <= b.hi.array() + m).all();
    });
  };
  for (std::size_t c = 0; c < nc; ++c) {
    if (g.state[c] >= 3 && in_confirmed(g.cp[c])) seed[c] = 1;
  }
  for (const TestedKeypoint& t : tested) {
    if (!t.candidate) continue;
    const std::ptrdiff_t c = cell_of(t.u, t.v);
    if (c < 0 || zall[static_cast<std::size_t>(c)] <= 0.0F) continue;
    const auto cu = static_cast<std::size_t>(c);
    if (std::abs(zall[cu] - t.z) > edge_thr(prm, t.z) || !in_confirmed(pall[cu])) continue;
    seed[cu] = 1;
  }
  if (carry) {
    const Eigen::Isometry3d T_cam_world = T_world_cam.inverse();
    for (const Eigen::Vector3f& w : prev_world) {
      const Eigen::Vector3d q = T_cam_world * w.cast<double>();
      if (q.z() < 0.1) continue;
      const Eigen::Vector2d uv = camera.project(q);
      const std::ptrdiff_t c = cell_of(uv.x(), uv.y());
      if (c < 0 || zall[static_cast<std::size_t>(c)] <= 0.0F) continue;
      const auto cu = static_cast<std::size_t>(c);
      if (seed[cu] == 0 && std::abs(zall[cu] - q.z()) <= edge_thr(prm, q.z())) seed[cu] = 2;
    }
  }
  return seed;
}

// Ground: the floor prior of preprocess on every fourth cell with depth in both directions
// (1/16 of the grid, ~1,200 points at 640x480: plenty for a plane, a sixteenth of the cost).
Floor find_floor(const GeometricMotionParams& prm, const WarpGrid& g, SegmentCounts& out) {
  const std::size_t nc = g.state.size();
  const std::vector<float>& zall = g.cz;
  const std::vector<Eigen::Vector3f>& pall = g.cp;
  Floor fl;
  fl.ground.assign(nc, 0);
  std::vector<std::uint8_t>& ground = fl.ground;
  Eigen::Vector4d& floor = fl.plane;
  Eigen::Vector3d& e1 = fl.e1;
  Eigen::Vector3d& e2 = fl.e2;
  std::vector<Eigen::Vector3f> pts;
  for (int j = 0; j < g.gh; j += 4) {
    for (int i = 0; i < g.gw; i += 4) {
      const auto c = static_cast<std::size_t>(j * g.gw + i);
      if (zall[c] > 0.0F) pts.push_back(pall[c]);
    }
  }
  RansacPlaneParams rp = PreprocessParams::make_default_ground();
  rp.distance_threshold = prm.min_depth_residual / 2.0;
  Points3f cloud(static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t k = 0; k < pts.size(); ++k) cloud.row(static_cast<Eigen::Index>(k)) = pts[k];
  const RansacPlaneResult pl = ransac_plane(cloud, rp);
  // A plane carrying a few cells is not the floor (same rule as preprocess's default).
  if (pl.found && static_cast<double>(pl.inliers.size()) >=
                      PreprocessParams{}.min_ground_fraction * static_cast<double>(pts.size())) {
    out.ground_found = true;
    floor = pl.plane;
    // Two horizontal axes: the camera's x (or z when x is nearly vertical) made orthogonal to
    // the floor normal, and their cross product.
    const Eigen::Vector3d up = pl.plane.head<3>();
    const Eigen::Vector3d ref =
        std::abs(up.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitZ();
    e1 = (ref - up * up.dot(ref)).normalized();
    e2 = up.cross(e1);
    const Eigen::Vector3d n = pl.plane.head<3>();
    for (std::size_t c = 0; c < nc; ++c) {
      if (zall[c] <= 0.0F) continue;
      const double dist = std::abs(n.dot(pall[c].cast<double>()) + pl.plane.w());
      const double z = zall[c];
      if (dist < std::max<double>(prm.min_depth_residual, 3.0 * sigma0(prm, z))) ground[c] = 1;
    }
  }
  return fl;
}

// Region growing from the seeds; returns the cells kept for the mask.
std::vector<std::uint8_t> grow_regions(const GeometricMotionParams& prm, const WarpGrid& g,
                                       const std::vector<std::uint8_t>& seed, const Floor& fl,
                                       SegmentCounts& out) {
  const std::size_t nc = g.state.size();
  const std::vector<float>& zall = g.cz;
  const std::vector<Eigen::Vector3f>& pall = g.cp;
  const std::vector<std::uint8_t>& ground = fl.ground;
  const Eigen::Vector4d& floor = fl.plane;
  const Eigen::Vector3d& e1 = fl.e1;
  const Eigen::Vector3d& e2 = fl.e2;
  // Region growing from the seeds. label: -1 unvisited, k >= 0 region k, -2 a leaked region.
  std::vector<int> label(nc, -1);
  std::vector<std::size_t> stack;
  std::vector<std::size_t> cells;
  std::vector<std::uint8_t> keep(nc, 0);
  const auto continuous = [&](std::size_t a, std::size_t b) {
    return std::abs(zall[a] - zall[b]) <= edge_thr(prm, std::max(zall[a], zall[b]));
  };
  int num_regions = 0;
  for (std::size_t c0 = 0; c0 < nc; ++c0) {
    if (seed[c0] == 0 || label[c0] != -1) continue;
    if (ground[c0] != 0) continue;  // a seed on the floor (a foot's band) grows nothing
    Box3 box;
    Eigen::Vector2d hlo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d hhi = -hlo;
    bool leaked = false;
    bool joined_leak = false;  // touched an earlier leaked region: part of it, not a new one
    cells.assign(1, c0);
    label[c0] = num_regions;
    stack.assign(1, c0);
    while (!stack.empty() && !leaked) {
      const std::size_t c = stack.back();
      stack.pop_back();
      const Eigen::Vector3d p = pall[c].cast<double>();
      box.add(p);
      if (box.size().maxCoeff() > prm.max_object_size) {
        leaked = true;
        break;
      }
      // With a floor: an object is at most max_object_width wide along the floor (in the
      // floor's own axes) and max_object_size high. A region that grows wider or higher is
      // joined to static structure (a wall, a table top, a cupboard).
      if (out.ground_found) {
        const Eigen::Vector2d h(e1.dot(p), e2.dot(p));
        hlo = hlo.cwiseMin(h);
        hhi = hhi.cwiseMax(h);
        if ((hhi - hlo).maxCoeff() > prm.max_object_width ||
            floor.head<3>().dot(p) + floor.w() > prm.max_object_size) {
          leaked = true;
          break;
        }
      }
      const int i = static_cast<int>(c % static_cast<std::size_t>(g.gw));
      const int j = static_cast<int>(c / static_cast<std::size_t>(g.gw));
      for (int dj = -1; dj <= 1 && !leaked; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          const int ii = i + di;
          const int jj = j + dj;
          if (ii < 0 || jj < 0 || ii >= g.gw || jj >= g.gh) continue;
          const auto n = static_cast<std::size_t>(jj * g.gw + ii);
          if (zall[n] <= 0.0F || ground[n] != 0 || !continuous(c, n)) continue;
          if (label[n] == -2) {  // touches a region that leaked: so does this one
            leaked = true;
            joined_leak = true;
            break;
          }
          if (label[n] != -1) continue;
          label[n] = num_regions;
          cells.push_back(n);
          stack.push_back(n);
        }
      }
    }
    if (leaked) {
      out.leaked += joined_leak ? 0 : 1;
      for (const std::size_t c : cells) {
        label[c] = -2;
        if (seed[c] == 1) keep[c] = 1;  // this frame's evidence; a carried seed may be the leak
      }
    } else {
      ++out.segments;
      for (const std::size_t c : cells) keep[c] = 1;
    }
    ++num_regions;
  }
  return keep;
}

// The mask: segment cells and the band of pixels around them that is not behind them.
void paint_mask(const GeometricMotionParams& prm, const cv::Mat& depth, const PinholeCamera& camera,
                const Eigen::Isometry3d& T_world_cam, const WarpGrid& g,
                const std::vector<std::uint8_t>& keep, cv::Mat* mask,
                std::vector<Eigen::Vector3f>* segment_world, SegmentCounts& out) {
  const std::size_t nc = g.state.size();
  const std::vector<float>& zall = g.cz;
  const std::vector<Eigen::Vector3f>& pall = g.cp;
  *mask = cv::Mat::zeros(depth.rows, depth.cols, CV_8UC1);
  const int r = g.s / 2 + 1;
  const double ds = camera.depth_scale;
  for (std::size_t c = 0; c < nc; ++c) {
    if (keep[c] == 0) continue;
    ++out.cells;
    segment_world->push_back((T_world_cam * pall[c].cast<double>()).cast<float>());
    const int u = g.off + static_cast<int>(c % static_cast<std::size_t>(g.gw)) * g.s;
    const int v = g.off + static_cast<int>(c / static_cast<std::size_t>(g.gw)) * g.s;
    const double zmax = zall[c] + edge_thr(prm, zall[c]);
    for (int y = std::max(0, v - r); y <= std::min(depth.rows - 1, v + r); ++y) {
      const auto* drow = depth.ptr<std::uint16_t>(y);
      auto* mrow = mask->ptr<std::uint8_t>(y);
      for (int x = std::max(0, u - r); x <= std::min(depth.cols - 1, u + r); ++x) {
        if (mrow[x] != 0 || drow[x] == 0) continue;
        if (drow[x] / ds <= zmax) mrow[x] = 255;
      }
    }
  }
}

}  // namespace

// Object segments (step 6b of GeometricMotionSource::detect). Seeds: the moved-in cells and the
// candidate keypoints inside the evidence boxes of the objects confirmed this frame (`confirmed`,
// camera frame, grown by box_margin), and last frame's segment (`prev_world`) carried into this
// frame where the surface is still there (same depth within the edge threshold) and inside a held
// object's world box — so a person who stops stays masked while the object is held. Each seed
// grows over usable cells (8-neighbourhood up to two cells, as the warp components) while the
// depth stays continuous, never onto the ground: the dominant plane of the grid with the floor
// prior of preprocess (−y within 30°, camera above it), cells within max(min_depth_residual, 3σ(z))
// of it. A region whose camera-frame box outgrows max_object_size has leaked into static
// structure (a wall or furniture it touches): it is dropped and only its seeds are kept. The mask
// paints each segment cell's s×s block and the pixels within s + warp_window of it that are not
// behind it (the silhouette band the grid skipped as a depth edge).
SegmentCounts grow_segments(const GeometricMotionParams& prm, const cv::Mat& depth,
                            const PinholeCamera& camera, const Eigen::Isometry3d& T_world_cam,
                            const std::vector<Box3>& confirmed, bool carry,
                            const std::vector<TestedKeypoint>& tested,
                            const std::vector<Eigen::Vector3f>& prev_world, const WarpGrid& g,
                            cv::Mat* mask, std::vector<Eigen::Vector3f>* segment_world) {
  SegmentCounts out;
  const std::vector<std::uint8_t> seed =
      seed_cells(prm, camera, T_world_cam, confirmed, carry, tested, prev_world, g);
  if (std::none_of(seed.begin(), seed.end(), [](std::uint8_t x) { return x != 0; })) return out;
  const Floor fl = find_floor(prm, g, out);
  const std::vector<std::uint8_t> keep = grow_regions(prm, g, seed, fl, out);
  paint_mask(prm, depth, camera, T_world_cam, g, keep, mask, segment_world, out);
  return out;
}

}  // namespace ds3d::slam::detail
