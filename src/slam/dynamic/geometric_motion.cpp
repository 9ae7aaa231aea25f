// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/dynamic/geometric_motion.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include <Eigen/Cholesky>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/errors.hpp"
#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/preprocess/preprocess.hpp"
#include "ds3d/preprocess/ransac_plane.hpp"

namespace ds3d::slam {

void GeometricMotionParams::validate() const {
  constexpr const char* f = "ds3d::slam::GeometricMotionParams";
  DS3D_CHECK(num_features > 0, f, ": num_features must be > 0 (got ", num_features, ")");
  DS3D_CHECK(reference_gap >= 1, f, ": reference_gap must be >= 1 (got ", reference_gap, ")");
  DS3D_CHECK(max_match_distance >= 1 && max_match_distance <= 256, f,
             ": max_match_distance must be in [1, 256] (got ", max_match_distance, ")");
  DS3D_CHECK(std::isfinite(match_ratio) && match_ratio > 0 && match_ratio <= 1, f,
             ": match_ratio must be in (0, 1] (got ", match_ratio, ")");
  DS3D_CHECK(ransac_iterations >= 1, f, ": ransac_iterations must be >= 1 (got ", ransac_iterations,
             ")");
  DS3D_CHECK(std::isfinite(chi2_2dof) && chi2_2dof > 0, f, ": chi2_2dof must be > 0 (got ",
             chi2_2dof, ")");
  DS3D_CHECK(std::isfinite(moving_chi2) && moving_chi2 > 0, f, ": moving_chi2 must be > 0 (got ",
             moving_chi2, ")");
  DS3D_CHECK(std::isfinite(min_pixel_sigma) && min_pixel_sigma > 0, f,
             ": min_pixel_sigma must be > 0 (got ", min_pixel_sigma, ")");
  DS3D_CHECK(std::isfinite(depth_noise) && depth_noise >= 0, f, ": depth_noise must be >= 0 (got ",
             depth_noise, ")");
  DS3D_CHECK(std::isfinite(min_depth_residual) && min_depth_residual > 0, f,
             ": min_depth_residual must be > 0 (got ", min_depth_residual, ")");
  DS3D_CHECK(depth_window >= 0, f, ": depth_window must be >= 0 (got ", depth_window, ")");
  DS3D_CHECK(std::isfinite(min_inlier_ratio) && min_inlier_ratio >= 0 && min_inlier_ratio <= 1, f,
             ": min_inlier_ratio must be in [0, 1] (got ", min_inlier_ratio, ")");
  DS3D_CHECK(min_pose_inliers >= 6, f, ": min_pose_inliers must be >= 6 (got ", min_pose_inliers,
             ")");
  DS3D_CHECK(warp_stride >= 1, f, ": warp_stride must be >= 1 (got ", warp_stride, ")");
  DS3D_CHECK(warp_gap >= 1, f, ": warp_gap must be >= 1 (got ", warp_gap, ")");
  DS3D_CHECK(warp_window >= 0, f, ": warp_window must be >= 0 (got ", warp_window, ")");
  DS3D_CHECK(std::isfinite(warp_chi2) && warp_chi2 > 0, f, ": warp_chi2 must be > 0 (got ",
             warp_chi2, ")");
  DS3D_CHECK(std::isfinite(min_warp_area) && min_warp_area > 0, f,
             ": min_warp_area must be > 0 (got ", min_warp_area, ")");
  DS3D_CHECK(std::isfinite(max_object_width) && max_object_width > 0, f,
             ": max_object_width must be > 0 (got ", max_object_width, ")");
  DS3D_CHECK(std::isfinite(max_speed) && max_speed >= 0, f, ": max_speed must be >= 0 (got ",
             max_speed, ")");
  DS3D_CHECK(std::isfinite(min_band_support) && min_band_support >= 0 && min_band_support <= 1, f,
             ": min_band_support must be in [0, 1] (got ", min_band_support, ")");
  DS3D_CHECK(std::isfinite(image_scale) && image_scale > 0 && image_scale <= 1, f,
             ": image_scale must be in (0, 1] (got ", image_scale, ")");
  DS3D_CHECK(std::isfinite(max_depth) && max_depth > 0, f, ": max_depth must be > 0 (got ",
             max_depth, ")");
  DS3D_CHECK(min_cluster_size >= 2, f, ": min_cluster_size must be >= 2 (got ", min_cluster_size,
             ")");
  DS3D_CHECK(min_samples >= 1, f, ": min_samples must be >= 1 (got ", min_samples, ")");
  DS3D_CHECK(std::isfinite(min_support) && min_support > 0 && min_support <= 1, f,
             ": min_support must be in (0, 1] (got ", min_support, ")");
  DS3D_CHECK(std::isfinite(max_object_size) && max_object_size > 0, f,
             ": max_object_size must be > 0 (got ", max_object_size, ")");
  DS3D_CHECK(std::isfinite(box_margin) && box_margin >= 0, f, ": box_margin must be >= 0 (got ",
             box_margin, ")");
  DS3D_CHECK(hold_frames >= 0, f, ": hold_frames must be >= 0 (got ", hold_frames, ")");
}

namespace {

OrbParams orb_params(const GeometricMotionParams& p) {
  OrbParams o;
  o.num_features = p.num_features;
  o.max_depth = p.max_depth;
  o.max_range = std::max(o.max_range, p.max_depth);
  return o;
}

// Ray through an undistorted pixel (z = 1).
Eigen::Vector3d ray(const PinholeCamera& c, const Eigen::Vector2f& u) {
  return {(u.x() - c.cx) / c.fx, (u.y() - c.cy) / c.fy, 1.0};
}

// Spread (max - min) of the valid depths [m] in a (2r+1)² window around (u, v); 0 if < 2 valid.
double depth_spread(const cv::Mat& depth, double scale, float u, float v, int r) {
  const int x0 = static_cast<int>(std::lround(u));
  const int y0 = static_cast<int>(std::lround(v));
  std::uint16_t lo = std::numeric_limits<std::uint16_t>::max();
  std::uint16_t hi = 0;
  for (int y = std::max(0, y0 - r); y <= std::min(depth.rows - 1, y0 + r); ++y) {
    const auto* row = depth.ptr<std::uint16_t>(y);
    for (int x = std::max(0, x0 - r); x <= std::min(depth.cols - 1, x0 + r); ++x) {
      if (row[x] == 0) continue;
      lo = std::min(lo, row[x]);
      hi = std::max(hi, row[x]);
    }
  }
  return hi > lo ? (hi - lo) / scale : 0.0;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The camera of an image resized to (w, h): intrinsics scaled about the pixel-centre convention;
// distortion is in normalised coordinates and does not change.
PinholeCamera resized_camera(const PinholeCamera& c, int w, int h) {
  PinholeCamera o = c;
  const double sx = static_cast<double>(w) / c.width;
  const double sy = static_cast<double>(h) / c.height;
  o.fx = c.fx * sx;
  o.fy = c.fy * sy;
  o.cx = (c.cx + 0.5) * sx - 0.5;
  o.cy = (c.cy + 0.5) * sy - 0.5;
  o.width = w;
  o.height = h;
  return o;
}

bool same_camera(const PinholeCamera& a, const PinholeCamera& b) {
  return a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.width == b.width &&
         a.height == b.height && a.k1 == b.k1 && a.k2 == b.k2 && a.p1 == b.p1 && a.p2 == b.p2 &&
         a.k3 == b.k3;
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
// for every cell with depth (also edge cells, state 0).
struct SegmentGrid {
  const std::vector<std::uint8_t>& state;
  const std::vector<float>& cz;            // depth of every cell with depth [m], 0 = none
  const std::vector<Eigen::Vector3f>& cp;  // its camera-frame point
  int gw, gh, s, off;
};

struct SegmentCounts {
  int cells = 0, segments = 0, leaked = 0;
  bool ground_found = false;
};

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
                            const std::vector<Eigen::Vector3f>& prev_world, const SegmentGrid& g,
                            cv::Mat* mask, std::vector<Eigen::Vector3f>* segment_world) {
  SegmentCounts out;
  const std::size_t nc = g.state.size();
  const auto sigma0 = [&](double z) { return static_cast<double>(prm.depth_noise) * z * z; };
  const auto edge_thr = [&](double z) {
    return std::max<double>(prm.min_depth_residual, 3.0 * std::sqrt(2.0) * sigma0(z));
  };
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
    if (std::abs(zall[cu] - t.z) > edge_thr(t.z) || !in_confirmed(pall[cu])) continue;
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
      if (seed[cu] == 0 && std::abs(zall[cu] - q.z()) <= edge_thr(q.z())) seed[cu] = 2;
    }
  }
  if (std::none_of(seed.begin(), seed.end(), [](std::uint8_t x) { return x != 0; })) return out;

  // Ground: the floor prior of preprocess on every fourth cell with depth in both directions
  // (1/16 of the grid, ~1,200 points at 640x480: plenty for a plane, a sixteenth of the cost).
  std::vector<std::uint8_t> ground(nc, 0);
  Eigen::Vector4d floor = Eigen::Vector4d::Zero();  // (n, d), n the unit up vector, when found
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX();    // horizontal axes of the floor, when found
  Eigen::Vector3d e2 = Eigen::Vector3d::UnitZ();
  {
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
        if (dist < std::max<double>(prm.min_depth_residual, 3.0 * sigma0(z))) ground[c] = 1;
      }
    }
  }

  // Region growing from the seeds. label: -1 unvisited, k >= 0 region k, -2 a leaked region.
  std::vector<int> label(nc, -1);
  std::vector<std::size_t> stack;
  std::vector<std::size_t> cells;
  std::vector<std::uint8_t> keep(nc, 0);
  const auto continuous = [&](std::size_t a, std::size_t b) {
    return std::abs(zall[a] - zall[b]) <= edge_thr(std::max(zall[a], zall[b]));
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

  // The mask: segment cells and the band of pixels around them that is not behind them.
  *mask = cv::Mat::zeros(depth.rows, depth.cols, CV_8UC1);
  const int r = g.s / 2 + 1;
  const double ds = camera.depth_scale;
  for (std::size_t c = 0; c < nc; ++c) {
    if (keep[c] == 0) continue;
    ++out.cells;
    segment_world->push_back((T_world_cam * pall[c].cast<double>()).cast<float>());
    const int u = g.off + static_cast<int>(c % static_cast<std::size_t>(g.gw)) * g.s;
    const int v = g.off + static_cast<int>(c / static_cast<std::size_t>(g.gw)) * g.s;
    const double zmax = zall[c] + edge_thr(zall[c]);
    for (int y = std::max(0, v - r); y <= std::min(depth.rows - 1, v + r); ++y) {
      const auto* drow = depth.ptr<std::uint16_t>(y);
      auto* mrow = mask->ptr<std::uint8_t>(y);
      for (int x = std::max(0, u - r); x <= std::min(depth.cols - 1, u + r); ++x) {
        if (mrow[x] != 0 || drow[x] == 0) continue;
        if (drow[x] / ds <= zmax) mrow[x] = 255;
      }
    }
  }
  return out;
}
}  // namespace

}  // namespace ds3d::slam

namespace ds3d::detail {

// Mutual best matches of two sets of 256-bit ORB descriptors (rows of CV_8UC1, 32 bytes) that
// pass Lowe's ratio test (Lowe 2004, §7.1), by one brute-force pass over all pairs that keeps the
// best and second best per row of `a` and the best per row of `b`. Same result as
// BFMatcher::knnMatch(a, b, 2) + BFMatcher::match(b, a) with the lowest index winning ties, at a
// fraction of the cost (hardware popcount, no per-call allocations of OpenCV's batch distance).
std::vector<cv::DMatch> mutual_ratio_matches(const cv::Mat& a, const cv::Mat& b, float ratio) {
  std::vector<cv::DMatch> out;
  if (a.rows == 0 || b.rows < 2 || a.cols != 32 || b.cols != 32) return out;
  const auto pack = [](const cv::Mat& m) {
    std::vector<std::array<std::uint64_t, 4>> v(static_cast<std::size_t>(m.rows));
    for (int r = 0; r < m.rows; ++r)
      std::memcpy(v[static_cast<std::size_t>(r)].data(), m.ptr(r), 32);
    return v;
  };
  const auto pa = pack(a);
  const auto pb = pack(b);
  const int na = a.rows;
  const int nb = b.rows;
  std::vector<int> best_of_b(static_cast<std::size_t>(nb), std::numeric_limits<int>::max());
  std::vector<int> best_idx_b(static_cast<std::size_t>(nb), -1);
  std::vector<std::array<int, 3>> best_of_a(static_cast<std::size_t>(na));  // d1, d2, index
  for (int i = 0; i < na; ++i) {
    const auto& x = pa[static_cast<std::size_t>(i)];
    int d1 = std::numeric_limits<int>::max();
    int d2 = d1;
    int j1 = -1;
    for (int j = 0; j < nb; ++j) {
      const auto& y = pb[static_cast<std::size_t>(j)];
      const int d = std::popcount(x[0] ^ y[0]) + std::popcount(x[1] ^ y[1]) +
                    std::popcount(x[2] ^ y[2]) + std::popcount(x[3] ^ y[3]);
      if (d < d1) {
        d2 = d1;
        d1 = d;
        j1 = j;
      } else if (d < d2) {
        d2 = d;
      }
      if (d < best_of_b[static_cast<std::size_t>(j)]) {
        best_of_b[static_cast<std::size_t>(j)] = d;
        best_idx_b[static_cast<std::size_t>(j)] = i;
      }
    }
    best_of_a[static_cast<std::size_t>(i)] = {d1, d2, j1};
  }
  for (int i = 0; i < na; ++i) {
    const auto [d1, d2, j1] = best_of_a[static_cast<std::size_t>(i)];
    if (j1 < 0 || !(static_cast<float>(d1) < ratio * static_cast<float>(d2))) continue;
    if (best_idx_b[static_cast<std::size_t>(j1)] != i) continue;
    out.emplace_back(i, j1, static_cast<float>(d1));
  }
  return out;
}

}  // namespace ds3d::detail

namespace ds3d::slam {

GeometricMotionSource::GeometricMotionSource(const GeometricMotionParams& params)
    : params_((params.validate(), params)), extractor_(orb_params(params)) {}

DynamicObjects GeometricMotionSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  stats_ = {};
  const std::size_t now = frame_count_++;
  DynamicObjects out;
  tested_.clear();
  moving_pixels_.clear();
  warp_tested_.clear();
  if (frame.depth.empty() || frame.depth.type() != CV_16UC1 || frame.rgb.empty()) return out;
  if (frame.depth.cols != camera.width || frame.depth.rows != camera.height) return out;

  // The source's own ORB runs on a reduced image (its camera `cs`); the dense warp and the
  // reported boxes use the full-resolution depth and `camera`.
  const int sw = std::max(1, static_cast<int>(std::lround(camera.width * params_.image_scale)));
  const int sh = std::max(1, static_cast<int>(std::lround(camera.height * params_.image_scale)));
  const PinholeCamera cs = resized_camera(camera, sw, sh);
  const double kx = static_cast<double>(camera.width) / sw;  // small → full pixel scale
  const double ky = static_cast<double>(camera.height) / sh;
  Past cur;
  cur.timestamp = frame.timestamp;
  if (sw == camera.width && sh == camera.height) {
    // A copy: the source keeps it for reference_gap frames, and the caller's buffer may be
    // reused or freed meanwhile (a cv::Mat over external memory, a numpy array).
    cur.depth_small = frame.depth.clone();
    cur.features = extractor_.extract(frame.rgb, frame.depth, cs);
  } else {
    cv::Mat rgb_small;
    cv::resize(frame.rgb, rgb_small, cv::Size(sw, sh), 0, 0, cv::INTER_AREA);
    cv::resize(frame.depth, cur.depth_small, cv::Size(sw, sh), 0, 0, cv::INTER_NEAREST);
    cur.features = extractor_.extract(rgb_small, cur.depth_small, cs);
  }
  {
    // Windowed min (0 wherever a pixel of the window lacks depth) and max: depth edges and holes.
    const int k = 2 * params_.warp_window + 1;
    const cv::Mat se = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k));
    cv::erode(frame.depth, cur.win_min, se);
    cv::dilate(frame.depth, cur.win_max, se);
  }

  // Reference: the oldest remembered frame whose world pose is chained from trusted poses. With
  // none (a long run of untrusted poses), the world frame of held objects is lost: restart.
  const Past* ref = nullptr;
  const std::size_t first_ref =
      history_.size() - std::min(history_.size(), static_cast<std::size_t>(params_.reference_gap));
  for (std::size_t h = first_ref; h < history_.size(); ++h) {
    if (history_[h].pose_valid) {
      ref = &history_[h];
      break;
    }
  }
  if (ref == nullptr) {
    held_.clear();
    candidates_.clear();
    if (!history_.empty()) ref = &history_.back();
  }
  cur.T_world_cam = ref != nullptr ? ref->T_world_cam : Eigen::Isometry3d::Identity();
  cur.pose_valid = history_.empty();  // the first frame defines the world frame

  const auto sigma0 = [&](double z) { return params_.depth_noise * z * z; };
  const auto sigma_z = [&](double z, double spread) {
    const double s = sigma0(z);
    return std::max<double>(params_.min_depth_residual / 3.0,
                            std::sqrt(s * s + 0.25 * spread * spread));
  };

  // Largest depth spread of a continuous surface in the keypoint window: that of the noise, or of
  // min_depth_residual (a slanted surface), whichever is larger.
  const auto edge_thr = [&](double z) {
    return std::max<double>(params_.min_depth_residual, 3.0 * std::sqrt(2.0) * sigma0(z));
  };
  struct Tested {
    Eigen::Vector3d uvz;  // raw pixel (full resolution) and current depth
    bool moving = false;
    double chi2 = 0;
  };
  std::vector<Tested> tested;
  Eigen::Isometry3d T_cur_ref = Eigen::Isometry3d::Identity();
  double pixel_sigma = params_.min_pixel_sigma;
  if (ref != nullptr) {
    const auto inside_held = [&](const Eigen::Vector3d& p_world) {
      return std::any_of(held_.begin(), held_.end(), [&](const Held& h) {
        const Eigen::Vector3d lo = h.corners_world.colwise().minCoeff().transpose();
        const Eigen::Vector3d hi = h.corners_world.colwise().maxCoeff().transpose();
        return (p_world.array() >= lo.array()).all() && (p_world.array() <= hi.array()).all();
      });
    };
    // 1. Mutual best matches that also pass Lowe's ratio test (Lowe 2004, §7.1): repeated texture
    // (keyboards, tiles) gives ambiguous descriptors whose mismatches share one wrong offset and
    // would form a dense "moving" cluster on static structure.
    const std::vector<cv::DMatch> matches = ds3d::detail::mutual_ratio_matches(
        cur.features.descriptors, ref->features.descriptors, params_.match_ratio);
    std::vector<std::pair<std::size_t, std::size_t>> pairs;  // (current, reference)
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    std::vector<cv::Point3f> obj_all;
    std::vector<cv::Point2f> img_all;
    for (const cv::DMatch& m : matches) {
      if (m.distance > static_cast<float>(params_.max_match_distance)) continue;
      const auto c = static_cast<std::size_t>(m.queryIdx);
      const auto r = static_cast<std::size_t>(m.trainIdx);
      if (!ref->features.has_depth(r)) continue;
      const Eigen::Vector3d p = ref->features.depth[r] * ray(cs, ref->features.undistorted[r]);
      const cv::Point3f pf(static_cast<float>(p.x()), static_cast<float>(p.y()),
                           static_cast<float>(p.z()));
      const cv::Point2f uc(cur.features.undistorted[c].x(), cur.features.undistorted[c].y());
      pairs.emplace_back(c, r);
      obj_all.push_back(pf);
      img_all.push_back(uc);
      if (!inside_held(ref->T_world_cam * p)) {
        obj.push_back(pf);
        img.push_back(uc);
      }
    }
    stats_.num_matches = static_cast<int>(pairs.size());
    // Known objects covering most matches would starve the pose: then use every match.
    if (static_cast<int>(obj.size()) < 2 * params_.min_pose_inliers) {
      obj = obj_all;
      img = img_all;
    }
    // 2. Robust pose T_cur_ref (EPnP-RANSAC, then Levenberg-Marquardt on the inliers). The
    //    inlier threshold is in pixels of the reduced image.
    if (static_cast<int>(obj.size()) >= params_.min_pose_inliers) {
      const cv::Matx33d K(cs.fx, 0, cs.cx, 0, cs.fy, cs.cy, 0, 0, 1);
      cv::Mat rvec;
      cv::Mat tvec;
      std::vector<int> inliers;
      const bool ok = cv::solvePnPRansac(
          obj, img, K, cv::noArray(), rvec, tvec, false, params_.ransac_iterations,
          static_cast<float>(std::sqrt(params_.chi2_2dof) * 1.5), 0.99, inliers, cv::SOLVEPNP_EPNP);
      const double ratio = static_cast<double>(inliers.size()) /
                           static_cast<double>(std::max<std::size_t>(obj.size(), 1));
      stats_.num_pose_inliers = static_cast<int>(inliers.size());
      if (ok && static_cast<int>(inliers.size()) >= params_.min_pose_inliers &&
          ratio >= params_.min_inlier_ratio) {
        std::vector<cv::Point3f> oi;
        std::vector<cv::Point2f> ii;
        for (const int i : inliers) {
          oi.push_back(obj[static_cast<std::size_t>(i)]);
          ii.push_back(img[static_cast<std::size_t>(i)]);
        }
        cv::solvePnP(oi, ii, K, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
        cv::Mat R;
        cv::Rodrigues(rvec, R);
        Eigen::Matrix3d Re;
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) Re(a, b) = R.at<double>(a, b);
        }
        T_cur_ref.linear() = Re;
        T_cur_ref.translation() =
            Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
        stats_.pose_ok = T_cur_ref.matrix().allFinite();
      }
    }
    if (stats_.pose_ok) {
      cur.T_world_cam = ref->T_world_cam * T_cur_ref.inverse();
      cur.pose_valid = true;
      // σ_px of this frame: the median reprojection error of all matches, in level-0 pixels per
      // pyramid scale, over the median of a 2-D Rayleigh (σ·√(2 ln 2)). Robust up to half the
      // matches being outliers, and it grows with blur and rolling-shutter distortion.
      std::vector<double> e;
      for (const auto& [c, r] : pairs) {
        const Eigen::Vector3d q =
            T_cur_ref * (ref->features.depth[r] * ray(cs, ref->features.undistorted[r]));
        if (q.z() <= 0.0) continue;
        const Eigen::Vector2d du(cs.fx * q.x() / q.z() + cs.cx - cur.features.undistorted[c].x(),
                                 cs.fy * q.y() / q.z() + cs.cy - cur.features.undistorted[c].y());
        e.push_back(du.norm() / extractor_.level_scale(cur.features.keypoints[c].octave));
      }
      pixel_sigma =
          std::max(params_.min_pixel_sigma, median_of(e) / std::sqrt(2.0 * std::log(2.0)));
      // 3. χ² (3 dof) of each keypoint's (Δu, Δv, Δz) with its own covariance.
      const Eigen::Matrix3d& R = T_cur_ref.linear();
      for (const auto& [c, r] : pairs) {
        if (!cur.features.has_depth(c)) continue;
        const double zr = ref->features.depth[r];
        const double zc = cur.features.depth[c];
        if (zr > params_.max_depth || zc > params_.max_depth) continue;
        const Eigen::Vector3d d = ray(cs, ref->features.undistorted[r]);
        const Eigen::Vector3d q = T_cur_ref * (zr * d);
        if (q.z() <= 0.1) continue;
        const Eigen::Vector2f& uc = cur.features.undistorted[c];
        const Eigen::Vector3d res(uc.x() - (cs.fx * q.x() / q.z() + cs.cx),
                                  uc.y() - (cs.fy * q.y() / q.z() + cs.cy), zc - q.z());
        // Jacobian of the prediction (u, v, z) with respect to the reference depth.
        const Eigen::Vector3d dq = R * d;
        const Eigen::Vector3d g(cs.fx * (dq.x() * q.z() - q.x() * dq.z()) / (q.z() * q.z()),
                                cs.fy * (dq.y() * q.z() - q.y() * dq.z()) / (q.z() * q.z()),
                                dq.z());
        const cv::Point2f& pc = cur.features.keypoints[c].pt;
        const cv::Point2f& pr = ref->features.keypoints[r].pt;
        // Keypoints on a depth discontinuity (silhouettes, T-junctions, thin structures) are not
        // fixed 3-D points: the corner slides along the occluding contour as the view changes,
        // and RGB-depth misregistration gives them either depth. They are no evidence either way.
        const double spr =
            depth_spread(ref->depth_small, cs.depth_scale, pr.x, pr.y, params_.depth_window);
        const double spc =
            depth_spread(cur.depth_small, cs.depth_scale, pc.x, pc.y, params_.depth_window);
        if (spr > edge_thr(zr) || spc > edge_thr(zc)) continue;
        const double szr = sigma_z(zr, spr);
        const double szc = sigma_z(zc, spc);
        const double sc = extractor_.level_scale(cur.features.keypoints[c].octave);
        const double sr = extractor_.level_scale(ref->features.keypoints[r].octave);
        const double spx2 = pixel_sigma * pixel_sigma * (sc * sc + sr * sr);
        Eigen::Matrix3d S = Eigen::Vector3d(spx2, spx2, szc * szc).asDiagonal();
        S += g * g.transpose() * (szr * szr);
        const double chi2 = res.dot(S.ldlt().solve(res));
        Tested t;
        t.uvz = Eigen::Vector3d((pc.x + 0.5) * kx - 0.5, (pc.y + 0.5) * ky - 0.5, zc);
        t.moving = std::isfinite(chi2) && chi2 > params_.moving_chi2;
        t.chi2 = std::isfinite(chi2) ? chi2 : 0.0;
        stats_.num_moving_keypoints += t.moving ? 1 : 0;
        tested.push_back(t);
      }
      stats_.num_tested = static_cast<int>(tested.size());
    }
  }
  stats_.pixel_sigma = pixel_sigma;

  // 4. Candidates: HDBSCAN of the moving keypoints in (u, v, z), metric scales; compactness and
  //    support tests.
  struct Candidate {
    Box3 box;  // camera frame, of the evidence
  };
  std::vector<Candidate> found;
  std::vector<Eigen::Vector3d> moving;
  std::vector<std::size_t> moving_idx;  // index into tested
  for (std::size_t i = 0; i < tested.size(); ++i) {
    const Tested& t = tested[i];
    TestedKeypoint k;
    k.u = static_cast<float>(t.uvz.x());
    k.v = static_cast<float>(t.uvz.y());
    k.z = static_cast<float>(t.uvz.z());
    k.chi2 = static_cast<float>(t.chi2);
    k.moving = t.moving;
    tested_.push_back(k);
    if (!t.moving) continue;
    moving.push_back(t.uvz);
    moving_idx.push_back(i);
  }
  // The warp grid (full resolution, stride s, first pixel s/2): cell c ↔ pixel (u, v).
  const int s = params_.warp_stride;
  const int off = s / 2;
  const int gw = camera.width > off ? (camera.width - 1 - off) / s + 1 : 0;
  const int gh = camera.height > off ? (camera.height - 1 - off) / s + 1 : 0;
  if (static_cast<int>(moving.size()) >= params_.min_cluster_size) {
    RowMatrixXd pts(static_cast<Eigen::Index>(moving.size()), 3);
    std::vector<double> zs;
    for (std::size_t i = 0; i < moving.size(); ++i) {
      pts.row(static_cast<Eigen::Index>(i)) = moving[i].transpose();
      zs.push_back(moving[i].z());
    }
    const double zmed = median_of(zs);
    HdbscanParams hp;
    hp.min_cluster_size = params_.min_cluster_size;
    hp.min_samples = params_.min_samples;
    const HdbscanResult h = hdbscan(pts, hp, {zmed / camera.fx, zmed / camera.fy, 1.0});
    for (int cl = 0; cl < h.num_clusters; ++cl) {
      Candidate cand;
      double u0 = 1e30, u1 = -1e30, v0 = 1e30, v1 = -1e30, z0 = 1e30, z1 = -1e30;
      for (std::size_t i = 0; i < moving.size(); ++i) {
        if (h.labels[i] != cl) continue;
        tested_[moving_idx[i]].cluster = cl;
        const Eigen::Vector3d& m = moving[i];
        cand.box.add(camera.back_project(m.x(), m.y(), m.z()));
        u0 = std::min(u0, m.x()), u1 = std::max(u1, m.x());
        v0 = std::min(v0, m.y()), v1 = std::max(v1, m.y());
        z0 = std::min(z0, m.z()), z1 = std::max(z1, m.z());
      }
      // Human-scale objects only: larger clusters are static structure under a wrong pose.
      if (cand.box.size().maxCoeff() > params_.max_object_size) continue;
      // Support: a moving object moves as a whole, so most tested keypoints in its region move;
      // false alarms on static structure are scattered among consistent keypoints.
      const double dz = 3.0 * sigma_z(z1, 0.0);
      int in_region = 0;
      int moving_in_region = 0;
      for (const Tested& t : tested) {
        if (t.uvz.x() < u0 || t.uvz.x() > u1 || t.uvz.y() < v0 || t.uvz.y() > v1) continue;
        if (t.uvz.z() < z0 - dz || t.uvz.z() > z1 + dz) continue;
        ++in_region;
        moving_in_region += t.moving ? 1 : 0;
      }
      if (moving_in_region < params_.min_support * in_region) continue;
      for (std::size_t i = 0; i < moving.size(); ++i) {
        if (h.labels[i] == cl) tested_[moving_idx[i]].candidate = true;
      }
      found.push_back(std::move(cand));
    }
  }

  // 5. Dense depth warp into the reference. Cell states: 0 no usable depth (missing, beyond
  //    max_depth, or on a depth edge), 1 usable, 2 also tested against the reference, 3 moved in.
  std::vector<std::uint8_t> state;
  std::vector<float> cz;
  std::vector<Eigen::Vector3f> cp;  // camera-frame point of each usable cell
  if (stats_.pose_ok && gw > 0 && gh > 0) {
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
        if (mnrow[u] == 0 || (mxrow[u] - mnrow[u]) / ds > edge_thr(z)) continue;
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
        if ((wref->win_max.at<std::uint16_t>(qv, qu) - rmn) / ds > edge_thr(zr)) continue;
        state[c] = 2;
        ++stats_.num_warp_tested;
        warp_tested_.emplace_back(static_cast<float>(u), static_cast<float>(v));
        // In front of every surface the reference saw around there: the space was empty.
        const double slope =
            per_px *
            std::max<double>(wref->win_max.at<std::uint16_t>(qv, qu) - rmn, mxrow[u] - mnrow[u]) /
            ds;
        const double sig = std::sqrt(sigma0(q.z()) * sigma0(q.z()) + sigma0(zr) * sigma0(zr) +
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
    // Depth-continuous connected components (8-neighbourhood) of the moved-in cells.
    const auto continuous = [&](std::size_t a, std::size_t b) {
      return std::abs(cz[a] - cz[b]) <= edge_thr(std::max(cz[a], cz[b]));
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
        const double dz = 3.0 * sigma_z(z1, 0.0);
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
        if (moved < params_.min_support * in_region &&
            foot_moved < params_.min_band_support * foot) {
          continue;
        }
      }
      ++stats_.num_warp_candidates;
      found.push_back(std::move(cand));
    }
  }

  // Keypoint and warp evidence of one object: merge candidates whose boxes touch (within
  // box_margin) while the union stays object-sized.
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t a = 0; a < found.size() && !merged; ++a) {
      for (std::size_t b = a + 1; b < found.size() && !merged; ++b) {
        if (!found[a].box.overlaps(found[b].box, params_.box_margin)) continue;
        Box3 u = found[a].box;
        u.add(found[b].box);
        if (u.size().maxCoeff() > params_.max_object_size) continue;
        found[a].box = u;
        found.erase(found.begin() + static_cast<std::ptrdiff_t>(b));
        merged = true;
      }
    }
  }
  stats_.num_candidates = static_cast<int>(found.size());

  // 6. Confirmation over consecutive frames, and holding in the world frame.
  const auto world_box = [&](const Box3& b, Eigen::Matrix<double, 8, 3>* corners) {
    const Eigen::Vector3d lo = b.lo.array() - params_.box_margin;
    const Eigen::Vector3d hi = b.hi.array() + params_.box_margin;
    Box3 w;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d corner((k & 1) != 0 ? hi.x() : lo.x(), (k & 2) != 0 ? hi.y() : lo.y(),
                                   (k & 4) != 0 ? hi.z() : lo.z());
      const Eigen::Vector3d p = cur.T_world_cam * corner;
      if (corners != nullptr) corners->row(k) = p.transpose();
      w.add(p);
    }
    return w;
  };
  std::vector<Held> candidates_now;
  std::vector<Box3> confirmed;  // camera-frame evidence boxes of the objects confirmed now
  for (const Candidate& cand : found) {
    Held obj;
    const Box3 ev = world_box(cand.box, &obj.corners_world);
    obj.lo_world = ev.lo;
    obj.hi_world = ev.hi;
    obj.last_seen = now;
    const auto confirms = [&](const Held& x) {
      Box3 xe;
      xe.lo = x.lo_world;
      xe.hi = x.hi_world;
      return ev.overlaps(xe, 0.0);
    };
    candidates_now.push_back(obj);
    if (std::none_of(candidates_.begin(), candidates_.end(), confirms) &&
        std::none_of(held_.begin(), held_.end(), confirms)) {
      continue;
    }
    // A new sighting replaces the held objects it overlaps: the object moved there.
    std::erase_if(held_, [&](const Held& x) { return x.last_seen != now && confirms(x); });
    held_.push_back(obj);
    confirmed.push_back(cand.box);
    ++stats_.num_new_objects;
  }
  candidates_ = std::move(candidates_now);
  std::erase_if(held_, [&](const Held& x) {
    return now - x.last_seen > static_cast<std::size_t>(params_.hold_frames);
  });
  stats_.T_world_cam = cur.T_world_cam;

  // 6b. Object segments: each object's evidence covers only what moved into empty space (the
  //     leading band of a walker) and its matched keypoints; grow it over the depth-continuous
  //     surface it lies on, as a pixel mask.
  std::vector<Eigen::Vector3f> segment_world;
  if (params_.segment_objects && cur.pose_valid && !state.empty() &&
      (!confirmed.empty() || (!held_.empty() && !segment_world_.empty()))) {
    const SegmentGrid g{state, cz, cp, gw, gh, s, off};
    const SegmentCounts sc =
        grow_segments(params_, frame.depth, camera, cur.T_world_cam, confirmed, !held_.empty(),
                      tested_, segment_world_, g, &out.pixel_mask, &segment_world);
    stats_.num_segment_cells = sc.cells;
    stats_.num_segments = sc.segments;
    stats_.num_segments_leaked = sc.leaked;
    stats_.ground_found = sc.ground_found;
  }
  segment_world_ = std::move(segment_world);
  // 7. Report held objects in the current camera frame; without a trusted pose their place in
  //    this frame is unknown, so nothing is reported (the masker carries the last regions).
  if (cur.pose_valid) {
    const Eigen::Isometry3d T_cam_world = cur.T_world_cam.inverse();
    for (const Held& x : held_) {
      Eigen::Matrix<float, 8, 3> c;
      for (int k = 0; k < 8; ++k) {
        c.row(k) = (T_cam_world * x.corners_world.row(k).transpose()).cast<float>().transpose();
      }
      out.boxes_3d.push_back(c);
    }
  }
  stats_.num_objects = static_cast<int>(out.boxes_3d.size());

  history_.push_back(std::move(cur));
  while (static_cast<int>(history_.size()) > std::max(params_.reference_gap, params_.warp_gap)) {
    history_.pop_front();
  }
  return out;
}

}  // namespace ds3d::slam
