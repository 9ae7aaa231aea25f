// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Implementation of dynamic_filter.hpp. Not API.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <optional>
#include <utility>
#include <vector>

#include "ds3d/dynamic/dynamic_filter.hpp"

namespace ds3d {

DS3D_CORE_INLINE void DynamicFilterParams::validate() const {
  constexpr const char* f = "ds3d::DynamicFilterParams";
  DS3D_CHECK(std::isfinite(min_score) && min_score >= 0.0F && min_score <= 1.0F, f,
             ": min_score must be in [0, 1] (got ", min_score, ")");
  DS3D_CHECK(std::isfinite(box_margin) && box_margin >= 0.0F && box_margin <= 1.0F, f,
             ": box_margin must be in [0, 1] (got ", box_margin, ")");
  DS3D_CHECK(min_cluster_size >= 2, f, ": min_cluster_size must be >= 2 (got ", min_cluster_size,
             ")");
  DS3D_CHECK(min_samples >= 1, f, ": min_samples must be >= 1 (got ", min_samples, ")");
  DS3D_CHECK(min_keypoints >= 2, f, ": min_keypoints must be >= 2 (got ", min_keypoints, ")");
  DS3D_CHECK(std::isfinite(depth_gap) && depth_gap > 0.0F, f, ": depth_gap must be > 0 (got ",
             depth_gap, ")");
  DS3D_CHECK(std::isfinite(max_object_depth) && max_object_depth > 0.0F, f,
             ": max_object_depth must be > 0 (got ", max_object_depth, ")");
  DS3D_CHECK(std::isfinite(depth_noise) && depth_noise >= 0.0F, f,
             ": depth_noise must be >= 0 (got ", depth_noise, ")");
  DS3D_CHECK(
      std::isfinite(min_vertical_span) && min_vertical_span >= 0.0F && min_vertical_span <= 1.0F, f,
      ": min_vertical_span must be in [0, 1] (got ", min_vertical_span, ")");
  DS3D_CHECK(carry_frames >= 0, f, ": carry_frames must be >= 0 (got ", carry_frames, ")");
  DS3D_CHECK(std::isfinite(carry_iou) && carry_iou > 0.0F && carry_iou <= 1.0F, f,
             ": carry_iou must be in (0, 1] (got ", carry_iou, ")");
  DS3D_CHECK(std::isfinite(carry_motion) && carry_motion >= 0.0F, f,
             ": carry_motion must be >= 0 (got ", carry_motion, ")");
  DS3D_CHECK(std::isfinite(support_margin) && support_margin >= 0.0F, f,
             ": support_margin must be >= 0 (got ", support_margin, ")");
}

inline std::optional<SolidBox> solid_from_corners(const Eigen::Matrix<float, 8, 3>& corners,
                                                  float margin, float tol) {
  constexpr const char* f = "ds3d::solid_from_corners";
  DS3D_CHECK(std::isfinite(margin) && margin >= 0.0F, f, ": margin must be >= 0 (got ", margin,
             ")");
  DS3D_CHECK(std::isfinite(tol) && tol > 0.0F, f, ": tol must be > 0 (got ", tol, ")");
  if (!corners.allFinite()) return std::nullopt;
  // Edge candidates: the other corners relative to corner 0. A cuboid has three orthogonal ones
  // (its edges at corner 0) whose sums are the remaining four.
  std::array<Eigen::Vector3d, 7> d;
  double scale = 0.0;
  for (int k = 0; k < 7; ++k) {
    d[static_cast<std::size_t>(k)] =
        (corners.row(k + 1) - corners.row(0)).transpose().cast<double>();
    scale = std::max(scale, d[static_cast<std::size_t>(k)].norm());
  }
  if (!(scale > 0.0)) return std::nullopt;
  const double t = static_cast<double>(tol) * scale;
  for (std::size_t i = 0; i < 7; ++i) {
    for (std::size_t j = i + 1; j < 7; ++j) {
      for (std::size_t k = j + 1; k < 7; ++k) {
        const Eigen::Vector3d& a = d[i];
        const Eigen::Vector3d& b = d[j];
        const Eigen::Vector3d& c = d[k];
        if (a.norm() <= t || b.norm() <= t || c.norm() <= t) continue;
        if (std::abs(a.dot(b)) > t * scale || std::abs(a.dot(c)) > t * scale ||
            std::abs(b.dot(c)) > t * scale) {
          continue;
        }
        const std::array<Eigen::Vector3d, 7> sums = {a, b, c, a + b, a + c, b + c, a + b + c};
        std::array<bool, 7> used{};
        bool all = true;
        for (const Eigen::Vector3d& s : sums) {
          bool found = false;
          for (std::size_t q = 0; q < 7 && !found; ++q) {
            if (!used[q] && (d[q] - s).norm() <= t) {
              used[q] = true;
              found = true;
            }
          }
          all = all && found;
        }
        if (!all) continue;
        SolidBox out;
        out.centre = (corners.row(0).transpose().cast<double>() + (a + b + c) / 2.0).cast<float>();
        out.axes.row(0) = a.normalized().cast<float>().transpose();
        out.axes.row(1) = b.normalized().cast<float>().transpose();
        out.axes.row(2) = c.normalized().cast<float>().transpose();
        out.half = Eigen::Vector3d(a.norm(), b.norm(), c.norm()).cast<float>() / 2.0F;
        out.margin = margin;
        return out;
      }
    }
  }
  return std::nullopt;
}

inline std::optional<ImageBox> project_box(const Eigen::Matrix<float, 8, 3>& corners_cam,
                                           const PinholeCamera& camera, double min_z) {
  constexpr const char* f = "ds3d::project_box";
  camera.validate(f);
  DS3D_CHECK(std::isfinite(min_z) && min_z > 0.0, f, ": min_z must be > 0 (got ", min_z, ")");
  DS3D_CHECK(corners_cam.allFinite(), f, ": corners_cam must be finite");
  // Hull of the box clipped to z >= min_z: the corners in front plus the crossings of every
  // corner pair with the plane (pairs include all 12 edges, so any corner order works; crossings
  // of diagonals lie inside the box and do not change the hull).
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d a = corners_cam.row(i).transpose().cast<double>();
    if (a.z() >= min_z) pts.push_back(a);
    for (int j = i + 1; j < 8; ++j) {
      const Eigen::Vector3d b = corners_cam.row(j).transpose().cast<double>();
      if ((a.z() - min_z) * (b.z() - min_z) < 0.0) {
        const double t = (min_z - a.z()) / (b.z() - a.z());
        pts.push_back(a + t * (b - a));
      }
    }
  }
  if (pts.empty()) return std::nullopt;
  double u0 = std::numeric_limits<double>::infinity();
  double v0 = u0;
  double z0 = u0;
  double u1 = -u0;
  double v1 = -u0;
  double z1 = -u0;
  for (const auto& p : pts) {
    const Eigen::Vector2d uv = camera.project(p);
    u0 = std::min(u0, uv.x());
    u1 = std::max(u1, uv.x());
    v0 = std::min(v0, uv.y());
    v1 = std::max(v1, uv.y());
    z0 = std::min(z0, p.z());
    z1 = std::max(z1, p.z());
  }
  u0 = std::max(u0, -0.5);
  v0 = std::max(v0, -0.5);
  u1 = std::min(u1, camera.width - 0.5);
  v1 = std::min(v1, camera.height - 0.5);
  if (!(u1 > u0) || !(v1 > v0)) return std::nullopt;
  ImageBox b;
  b.x_min = static_cast<float>(u0);
  b.y_min = static_cast<float>(v0);
  b.x_max = static_cast<float>(u1);
  b.y_max = static_cast<float>(v1);
  b.z_min = static_cast<float>(z0);
  b.z_max = static_cast<float>(z1);
  return b;
}

namespace detail {

inline bool valid_depth(float z) noexcept { return std::isfinite(z) && z > 0.0F; }

// `q` = (n, d) scaled to a unit normal; throws naming `fn` and `name` when it is not finite or
// its normal is zero.
inline Eigen::Vector4f unit_plane(const Eigen::Vector4f& q, const char* fn, const char* name) {
  const float nn = q.head<3>().norm();
  DS3D_CHECK(q.allFinite() && nn > 0.0F, fn, ": ", name,
             " must be finite with a non-zero normal (got ", q.x(), ", ", q.y(), ", ", q.z(), ", ",
             q.w(), ")");
  return q / nn;
}

// The support-plane rule: camera-frame point `p`, seen along `ray` = ∂p/∂z with depth noise
// `sigma_z`, lies within `margin` plus 3σ along the normal of the unit `plane` (the depth error
// moves the point along its ray: σ along the normal is σ(z)·|n·ray|).
inline bool near_plane(const Eigen::Vector4f& plane, const Eigen::Vector3f& p,
                       const Eigen::Vector3f& ray, float sigma_z, float margin) noexcept {
  const float dist = std::abs(plane.head<3>().dot(p) + plane.w());
  return dist <= margin + 3.0F * sigma_z * std::abs(plane.head<3>().dot(ray));
}

inline float median_of(std::vector<float> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Image rectangle and depth range of a set of keypoints (the dynamic region of a box).
struct Region {
  float u0 = std::numeric_limits<float>::infinity();
  float v0 = std::numeric_limits<float>::infinity();
  float u1 = -std::numeric_limits<float>::infinity();
  float v1 = -std::numeric_limits<float>::infinity();
  float z0 = std::numeric_limits<float>::infinity();
  float z1 = -std::numeric_limits<float>::infinity();
  void add(float u, float v, float z) {
    u0 = std::min(u0, u);
    u1 = std::max(u1, u);
    v0 = std::min(v0, v);
    v1 = std::max(v1, v);
    z0 = std::min(z0, z);
    z1 = std::max(z1, z);
  }
  [[nodiscard]] bool empty() const { return !(z1 >= z0); }
  [[nodiscard]] bool contains(float u, float v) const {
    return u >= u0 && u <= u1 && v >= v0 && v <= v1;
  }
};

// Column reads of keypoint row `i`: u, v, depth.
inline float key_u(const Eigen::Ref<const Keypoints3f>& k, std::size_t i) {
  return k(static_cast<Eigen::Index>(i), 0);
}
inline float key_v(const Eigen::Ref<const Keypoints3f>& k, std::size_t i) {
  return k(static_cast<Eigen::Index>(i), 1);
}
inline float key_z(const Eigen::Ref<const Keypoints3f>& k, std::size_t i) {
  return k(static_cast<Eigen::Index>(i), 2);
}

// Sensor depth noise σ(z) = depth_noise·z² (Khoshelham & Elberink 2012).
inline float depth_sigma(const DynamicFilterParams& p, float z) { return p.depth_noise * z * z; }
// Largest depth step within one object at depth z: depth_gap + 3σ(z).
inline float depth_gap_at(const DynamicFilterParams& p, float z) {
  return p.depth_gap + 3.0F * depth_sigma(p, z);
}

// Checks the camera, the support plane and every box; returns the unit support plane.
inline std::optional<Eigen::Vector4f> check_filter_inputs(
    const std::vector<ImageBox>& boxes, const PinholeCamera& camera,
    const std::optional<Eigen::Vector4f>& support_plane, const char* f) {
  camera.validate(f);
  std::optional<Eigen::Vector4f> plane;
  if (support_plane) plane = unit_plane(*support_plane, f, "support_plane");
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    const ImageBox& x = boxes[b];
    DS3D_CHECK(std::isfinite(x.x_min) && std::isfinite(x.y_min) && std::isfinite(x.x_max) &&
                   std::isfinite(x.y_max) && x.x_max >= x.x_min && x.y_max >= x.y_min,
               f, ": boxes[", b, "] must be finite with x_max >= x_min and y_max >= y_min (got ",
               x.x_min, ", ", x.y_min, ", ", x.x_max, ", ", x.y_max, ")");
    DS3D_CHECK(std::isfinite(x.score) && x.score >= 0.0F && x.score <= 1.0F, f, ": boxes[", b,
               "].score must be in [0, 1] (got ", x.score, ")");
    DS3D_CHECK(
        std::isfinite(x.z_min) && std::isfinite(x.z_max) && x.z_min >= 0.0F && x.z_max >= x.z_min,
        f, ": boxes[", b, "] depth range must satisfy 0 <= z_min <= z_max (got ", x.z_min, ", ",
        x.z_max, ")");
    if (x.solid) {
      const SolidBox& s = *x.solid;
      DS3D_CHECK(s.centre.allFinite() && s.axes.allFinite() && s.half.allFinite() &&
                     (s.half.array() >= 0.0F).all() && std::isfinite(s.margin) && s.margin >= 0.0F,
                 f, ": boxes[", b,
                 "].solid must be finite with half sizes >= 0 and margin >= 0 (got half ",
                 s.half.x(), ", ", s.half.y(), ", ", s.half.z(), ", margin ", s.margin, ")");
    }
  }
  return plane;
}

// Per-frame data of the keypoints, shared by every box.
struct FrameKeypoints {
  std::vector<std::uint8_t> finite_uv;     // 1 = u and v are finite
  std::vector<Eigen::Vector3f> ray;        // ∂p/∂z of each depth keypoint (metric gates only)
  std::vector<std::uint8_t> on_support;    // 1 = on the support plane (with a plane only)
  std::vector<std::uint8_t> seen_support;  // 1 = kept static on the plane in some box
  std::vector<std::uint8_t> seen_outside;  // 1 = outside the solid of some box (solids only)
};

// Flags the keypoints with a finite (u, v); counts the others in `num_non_finite`.
inline std::vector<std::uint8_t> finite_uv_flags(const Eigen::Ref<const Keypoints3f>& keypoints,
                                                 std::size_t& num_non_finite) {
  const auto n = static_cast<std::size_t>(keypoints.rows());
  std::vector<std::uint8_t> finite_uv(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    finite_uv[i] = std::isfinite(keypoints(r, 0)) && std::isfinite(keypoints(r, 1)) ? 1 : 0;
    if (finite_uv[i] == 0U) ++num_non_finite;
  }
  return finite_uv;
}

// Metric gates (solids, support plane) need each depth keypoint's ray ∂p/∂z = (x/z, y/z, 1),
// undistorted: computed once per frame, only when a gate is in use.
inline void metric_gates(const Eigen::Ref<const Keypoints3f>& keypoints,
                         const PinholeCamera& camera, const std::optional<Eigen::Vector4f>& plane,
                         bool any_solid, const DynamicFilterParams& params, FrameKeypoints& fk) {
  const auto n = static_cast<std::size_t>(keypoints.rows());
  if (any_solid || plane) {
    fk.ray.assign(n, Eigen::Vector3f::Zero());
    fk.on_support.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      if (fk.finite_uv[i] == 0U || !valid_depth(keypoints(r, 2))) continue;
      const Eigen::Vector2d xn = camera.undistort(
          {(keypoints(r, 0) - camera.cx) / camera.fx, (keypoints(r, 1) - camera.cy) / camera.fy});
      fk.ray[i] = Eigen::Vector3f(static_cast<float>(xn.x()), static_cast<float>(xn.y()), 1.0F);
      if (plane) {
        const float z = keypoints(r, 2);
        fk.on_support[i] = near_plane(*plane, fk.ray[i] * z, fk.ray[i], depth_sigma(params, z),
                                      params.support_margin)
                               ? 1
                               : 0;
      }
    }
  }
  fk.seen_support.assign(fk.on_support.empty() ? 0 : n, 0);
  fk.seen_outside.assign(any_solid ? n : 0, 0);
}

// The keypoints of one box.
struct BoxKeypoints {
  std::vector<std::size_t> in_box;      // finite (u, v) inside the rectangle
  std::vector<std::size_t> with_depth;  // of which with a depth that passed every gate
};

// Gathers the keypoints of `box`: rectangle, then, for those with depth, the box's depth range,
// the support plane and the solid. Gated keypoints are flagged in `gated`.
inline void gather_box(const Eigen::Ref<const Keypoints3f>& keypoints, const ImageBox& box,
                       const DynamicFilterParams& params, FrameKeypoints& fk,
                       std::vector<std::uint8_t>& gated, BoxKeypoints& kb) {
  const auto n = static_cast<std::size_t>(keypoints.rows());
  kb.in_box.clear();
  kb.with_depth.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    if (fk.finite_uv[i] == 0U || !box.contains(keypoints(r, 0), keypoints(r, 1))) continue;
    kb.in_box.push_back(i);
    const float z = keypoints(r, 2);
    if (!valid_depth(z)) continue;
    // A depth range (3-D box or carried region) excludes everything outside it outright.
    if (box.has_depth_range() && (z < box.z_min - 3.0F * depth_sigma(params, box.z_min) ||
                                  z > box.z_max + 3.0F * depth_sigma(params, box.z_max))) {
      continue;
    }
    // Floor texture is static, whichever box it falls in.
    if (!fk.on_support.empty() && fk.on_support[i] != 0U) {
      fk.seen_support[i] = 1;
      continue;
    }
    // An oriented 3-D box gates in 3-D: the rectangle and depth range of its projection also
    // hold the floor and furniture beside and below the object.
    if (box.solid && !box.solid->contains(fk.ray[i] * z, fk.ray[i], depth_sigma(params, z))) {
      fk.seen_outside[i] = 1;
      continue;
    }
    kb.with_depth.push_back(i);
    gated[i] = 1;
  }
}

// The foreground of one box, per with_depth entry.
struct Foreground {
  Region region;                     // union of the dynamic clusters
  std::vector<std::uint8_t> member;  // 1 = in a dynamic cluster
  std::vector<std::uint8_t> noise;   // 1 = HDBSCAN noise
};

// Image rectangle and depth range of each HDBSCAN cluster, and its median depth.
struct ClusterStats {
  std::vector<Region> cr;
  std::vector<float> med;
};

// Cluster statistics of a labelling of `with_depth` into `nc` clusters; flags the noise points.
inline ClusterStats cluster_stats(const Eigen::Ref<const Keypoints3f>& keypoints,
                                  const std::vector<std::size_t>& with_depth,
                                  const std::vector<std::int32_t>& labels, std::size_t nc,
                                  std::vector<std::uint8_t>& noise) {
  std::vector<std::vector<float>> cz(nc);
  ClusterStats s;
  s.cr.resize(nc);
  for (std::size_t k = 0; k < with_depth.size(); ++k) {
    if (labels[k] < 0) {
      noise[k] = 1;
      continue;
    }
    const auto c = static_cast<std::size_t>(labels[k]);
    cz[c].push_back(key_z(keypoints, with_depth[k]));
    s.cr[c].add(key_u(keypoints, with_depth[k]), key_v(keypoints, with_depth[k]),
                key_z(keypoints, with_depth[k]));
  }
  s.med.resize(nc);
  for (std::size_t c = 0; c < nc; ++c) s.med[c] = median_of(cz[c]);
  return s;
}

// Depth-continuous groups of clusters: [begin, end) ranges of `by_depth` (clusters by nearest
// depth).
struct DepthGroups {
  std::vector<std::size_t> by_depth;
  std::vector<std::pair<std::size_t, std::size_t>> groups;
};

// In order of nearest depth, a cluster joins the current group while its depth range [z0, z1]
// touches the group's (its near end within gap + 3σ of the group's far end) and its median lies
// within max_object_depth of the group's near end. A body that HDBSCAN splits into torso, arms
// and legs at different depths is one chain; the background seen around or through it is not (it
// lies a gap behind).
inline DepthGroups depth_groups(const ClusterStats& s, const DynamicFilterParams& params) {
  const std::vector<Region>& cr = s.cr;
  const std::vector<float>& med = s.med;
  const std::size_t nc = cr.size();
  DepthGroups d;
  std::vector<std::size_t>& by_depth = d.by_depth;
  by_depth.resize(nc);
  std::iota(by_depth.begin(), by_depth.end(), std::size_t{0});
  std::sort(by_depth.begin(), by_depth.end(), [&](std::size_t a, std::size_t b) {
    return cr[a].z0 < cr[b].z0 || (cr[a].z0 == cr[b].z0 && a < b);
  });
  for (std::size_t g0 = 0; g0 < nc;) {
    std::size_t g1 = g0 + 1;
    float far = cr[by_depth[g0]].z1;
    while (g1 < nc && cr[by_depth[g1]].z0 - far <= depth_gap_at(params, far) &&
           med[by_depth[g1]] - cr[by_depth[g0]].z0 <= params.max_object_depth) {
      far = std::max(far, cr[by_depth[g1]].z1);
      ++g1;
    }
    d.groups.emplace_back(g0, g1);
    g0 = g1;
  }
  return d;
}

// The foreground group: the shallowest that spans `need` pixels of the box height (a detected
// object fills its box; an occluder in front of part of it does not); if none does, the
// shallowest.
inline std::size_t choose_group(const DepthGroups& d, const ClusterStats& s, float need) {
  for (std::size_t g = 0; g < d.groups.size(); ++g) {
    float v0 = std::numeric_limits<float>::infinity();
    float v1 = -v0;
    for (std::size_t q = d.groups[g].first; q < d.groups[g].second; ++q) {
      v0 = std::min(v0, s.cr[d.by_depth[q]].v0);
      v1 = std::max(v1, s.cr[d.by_depth[q]].v1);
    }
    if (v1 - v0 >= need) return g;
  }
  return 0;
}

// HDBSCAN foreground of a box's depth keypoints; false (fg untouched) when no cluster is found.
inline bool hdbscan_foreground(const Eigen::Ref<const Keypoints3f>& keypoints,
                               const std::vector<std::size_t>& with_depth, const ImageBox& box,
                               const PinholeCamera& camera, const DynamicFilterParams& params,
                               BoxOutcome& out, Foreground& fg) {
  std::vector<float> zs(with_depth.size());
  for (std::size_t k = 0; k < with_depth.size(); ++k) zs[k] = key_z(keypoints, with_depth[k]);
  const double zmed = median_of(zs);
  RowMatrixXd pts(static_cast<Eigen::Index>(with_depth.size()), 3);
  for (std::size_t k = 0; k < with_depth.size(); ++k) {
    const auto r = static_cast<Eigen::Index>(k);
    pts(r, 0) = key_u(keypoints, with_depth[k]);
    pts(r, 1) = key_v(keypoints, with_depth[k]);
    pts(r, 2) = key_z(keypoints, with_depth[k]);
  }
  HdbscanParams hp;
  hp.min_cluster_size = params.min_cluster_size;
  hp.min_samples = params.min_samples;
  // Pixels → metres at the median depth: clustering becomes isotropic in metric space.
  const HdbscanResult h = hdbscan(pts, hp, {zmed / camera.fx, zmed / camera.fy, 1.0});
  out.num_clusters = h.num_clusters;
  if (h.num_clusters == 0) return false;
  const std::vector<std::int32_t>& labels = h.labels;
  const auto nc = static_cast<std::size_t>(h.num_clusters);
  const ClusterStats s = cluster_stats(keypoints, with_depth, labels, nc, fg.noise);
  const DepthGroups d = depth_groups(s, params);
  const float need = params.min_vertical_span * box.height();
  const std::size_t chosen = choose_group(d, s, need);
  std::vector<std::uint8_t> dyn_cluster(nc, 0);
  for (std::size_t q = d.groups[chosen].first; q < d.groups[chosen].second; ++q) {
    const std::size_t c = d.by_depth[q];
    dyn_cluster[c] = 1;
    fg.region.u0 = std::min(fg.region.u0, s.cr[c].u0);
    fg.region.u1 = std::max(fg.region.u1, s.cr[c].u1);
    fg.region.v0 = std::min(fg.region.v0, s.cr[c].v0);
    fg.region.v1 = std::max(fg.region.v1, s.cr[c].v1);
    fg.region.z0 = std::min(fg.region.z0, s.cr[c].z0);
    fg.region.z1 = std::max(fg.region.z1, s.cr[c].z1);
  }
  for (std::size_t k = 0; k < with_depth.size(); ++k) {
    if (labels[k] >= 0 && dyn_cluster[static_cast<std::size_t>(labels[k])] != 0U) {
      fg.member[k] = 1;
    }
  }
  return true;
}

// Depth-gap split: sorted depths; groups end at gaps wider than gap + 3σ. The foreground is the
// first group holding at least a fifth of the points (or min_samples), so that a stray flying
// pixel in front does not become "the object".
inline void depth_gap_foreground(const Eigen::Ref<const Keypoints3f>& keypoints,
                                 const std::vector<std::size_t>& with_depth,
                                 const DynamicFilterParams& params, Foreground& fg) {
  const auto kz = [&](std::size_t i) { return key_z(keypoints, i); };
  std::vector<std::size_t> order(with_depth.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const float za = kz(with_depth[a]);
    const float zb = kz(with_depth[b]);
    return za < zb || (za == zb && a < b);
  });
  const std::size_t need = std::min(
      order.size(),
      std::max<std::size_t>(static_cast<std::size_t>(params.min_samples), (order.size() + 4) / 5));
  std::size_t begin = 0;
  while (begin < order.size()) {
    std::size_t end = begin + 1;
    while (end < order.size() && kz(with_depth[order[end]]) - kz(with_depth[order[end - 1]]) <=
                                     depth_gap_at(params, kz(with_depth[order[end - 1]]))) {
      ++end;
    }
    if (end - begin >= need || end == order.size()) {
      for (std::size_t k = begin; k < end; ++k) {
        fg.member[order[k]] = 1;
        const std::size_t i = with_depth[order[k]];
        fg.region.add(key_u(keypoints, i), key_v(keypoints, i), kz(i));
      }
      break;
    }
    begin = end;
  }
  std::fill(fg.noise.begin(), fg.noise.end(), 0);
}

// The foreground of a box: HDBSCAN clusters, or the depth-gap fallback when the box has too few
// depth keypoints or HDBSCAN finds no cluster (sets out.num_clusters and out.fallback).
inline Foreground box_foreground(const Eigen::Ref<const Keypoints3f>& keypoints,
                                 const std::vector<std::size_t>& with_depth, const ImageBox& box,
                                 const PinholeCamera& camera, const DynamicFilterParams& params,
                                 BoxOutcome& out) {
  Foreground fg;
  fg.member.assign(with_depth.size(), 0);
  fg.noise.assign(with_depth.size(), 0);
  bool use_fallback = with_depth.size() < static_cast<std::size_t>(params.min_keypoints);
  if (!use_fallback) {
    use_fallback = !hdbscan_foreground(keypoints, with_depth, box, camera, params, out, fg);
  }
  if (use_fallback && !with_depth.empty()) {
    depth_gap_foreground(keypoints, with_depth, params, fg);
    out.fallback = true;
  }
  return fg;
}

// Mark: dynamic clusters; noise in the foreground's depth range and, unless the box has its own
// depth range (then box + range already gate in 3-D), in its rectangle; keypoints without depth
// in the rectangle (or anywhere in the box when no depth was seen at all). Returns the number of
// keypoints of this box marked dynamic.
inline int mark_box(const Eigen::Ref<const Keypoints3f>& keypoints, const BoxKeypoints& kb,
                    const Foreground& f, const ImageBox& box, const DynamicFilterParams& params,
                    bool saw_depth, DynamicFilterResult& res) {
  const Region& fg = f.region;
  const auto ku = [&](std::size_t i) { return key_u(keypoints, i); };
  const auto kv = [&](std::size_t i) { return key_v(keypoints, i); };
  const auto kz = [&](std::size_t i) { return key_z(keypoints, i); };
  int marked = 0;
  const auto mark = [&](std::size_t i) {
    if (res.dynamic[i] == 0U) {
      res.dynamic[i] = 1;
      ++res.num_dynamic;
    }
    ++marked;
  };
  for (std::size_t k = 0; k < kb.with_depth.size(); ++k) {
    const std::size_t i = kb.with_depth[k];
    if (f.member[k] != 0U) {
      mark(i);
    } else if (f.noise[k] != 0U && !fg.empty() &&
               (box.has_depth_range() || fg.contains(ku(i), kv(i))) &&
               kz(i) >= fg.z0 - 3.0F * depth_sigma(params, fg.z0) &&
               kz(i) <= fg.z1 + 3.0F * depth_sigma(params, fg.z1)) {
      mark(i);
    }
  }
  for (const std::size_t i : kb.in_box) {
    if (valid_depth(kz(i))) continue;
    if ((!saw_depth && !box.has_depth_range()) || (!fg.empty() && fg.contains(ku(i), kv(i)))) {
      mark(i);
    }
  }
  return marked;
}

// The dynamic region of a box (its foreground's rectangle and depth range), to carry to the
// next frame; it keeps the box's score, label and solid.
inline ImageBox foreground_region(const Region& fg, const ImageBox& box) {
  ImageBox region;
  region.x_min = fg.u0;
  region.y_min = fg.v0;
  region.x_max = fg.u1;
  region.y_max = fg.v1;
  region.z_min = fg.z0;
  region.z_max = fg.z1;
  region.score = box.score;
  region.label = box.label;
  region.solid = box.solid;
  return region;
}

}  // namespace detail

DS3D_CORE_INLINE std::vector<std::pair<ImageBox, int>> DynamicFeatureFilter::work_boxes(
    const std::vector<ImageBox>& boxes, const PinholeCamera& camera,
    std::size_t& num_ignored) const {
  const float img_u1 = static_cast<float>(camera.width) - 0.5F;
  const float img_v1 = static_cast<float>(camera.height) - 0.5F;
  std::vector<std::pair<ImageBox, int>> work;  // box, age (-1 = detection)
  for (const ImageBox& x : boxes) {
    if (x.score < params_.min_score) {
      ++num_ignored;
      continue;
    }
    const float mu = params_.box_margin * x.width();
    const float mv = params_.box_margin * x.height();
    const float x_min = std::max(x.x_min - mu, -0.5F);
    const float y_min = std::max(x.y_min - mv, -0.5F);
    const float x_max = std::min(x.x_max + mu, img_u1);
    const float y_max = std::min(x.y_max + mv, img_v1);
    if (!(x_max > x_min) || !(y_max > y_min)) {
      ++num_ignored;
      continue;
    }
    // Copied from `x` in place (GCC 12 warns, wrongly, on copying a local with an empty solid).
    ImageBox& g = work.emplace_back(x, -1).first;
    g.x_min = x_min;
    g.y_min = y_min;
    g.x_max = x_max;
    g.y_max = y_max;
  }
  const std::size_t num_detections = work.size();
  for (const Carried& c : carried_) {
    bool covered = false;
    for (std::size_t k = 0; k < num_detections; ++k) {
      covered = covered || work[k].first.iou(c.region) >= params_.carry_iou;
    }
    if (covered) continue;
    // The object may have moved by carry_motion metres: grow the region by that much.
    ImageBox g = c.region;
    const float z = std::max(g.z_min, 0.1F);
    const auto du = static_cast<float>(camera.fx) * params_.carry_motion / z;
    const auto dv = static_cast<float>(camera.fy) * params_.carry_motion / z;
    g.x_min = std::max(g.x_min - du, -0.5F);
    g.y_min = std::max(g.y_min - dv, -0.5F);
    g.x_max = std::min(g.x_max + du, img_u1);
    g.y_max = std::min(g.y_max + dv, img_v1);
    g.z_min = std::max(0.0F, g.z_min - params_.carry_motion);
    g.z_max = g.z_max + params_.carry_motion;
    // A region found in a solid box keeps that box, grown by the same motion.
    if (g.solid) g.solid->margin += params_.carry_motion;
    if (g.x_max > g.x_min && g.y_max > g.y_min) work.emplace_back(g, c.age);
  }
  return work;
}

DS3D_CORE_INLINE DynamicFilterResult DynamicFeatureFilter::filter(
    Eigen::Ref<const Keypoints3f> keypoints, const std::vector<ImageBox>& boxes,
    const PinholeCamera& camera, const std::optional<Eigen::Vector4f>& support_plane) {
  constexpr const char* f = "ds3d::DynamicFeatureFilter::filter";
  const std::optional<Eigen::Vector4f> plane =
      detail::check_filter_inputs(boxes, camera, support_plane, f);

  const auto n = static_cast<std::size_t>(keypoints.rows());
  DynamicFilterResult res;
  res.dynamic.assign(n, 0);
  res.gated.assign(n, 0);
  detail::FrameKeypoints fk;
  fk.finite_uv = detail::finite_uv_flags(keypoints, res.num_non_finite);

  // Boxes to process: detections (grown, clipped), then carried regions no detection covers.
  const std::vector<std::pair<ImageBox, int>> work =
      work_boxes(boxes, camera, res.num_ignored_boxes);
  const bool any_solid = std::any_of(work.begin(), work.end(),
                                     [](const auto& w) { return w.first.solid.has_value(); });
  detail::metric_gates(keypoints, camera, plane, any_solid, params_, fk);

  std::vector<Carried> next;
  detail::BoxKeypoints kb;
  for (const auto& [box, age] : work) {
    BoxOutcome out;
    out.box = box;
    out.carried = age >= 0;
    detail::gather_box(keypoints, box, params_, fk, res.gated, kb);
    out.num_keypoints = static_cast<int>(kb.in_box.size());
    out.num_with_depth = static_cast<int>(kb.with_depth.size());
    const detail::Foreground fg =
        detail::box_foreground(keypoints, kb.with_depth, box, camera, params_, out);
    out.num_dynamic =
        detail::mark_box(keypoints, kb, fg, box, params_, out.num_with_depth > 0, res);
    if (!fg.region.empty()) {
      out.z_front = fg.region.z0;
      out.z_back = fg.region.z1;
      const int new_age = age < 0 ? 0 : age + 1;
      if (new_age < params_.carry_frames) {
        next.push_back({detail::foreground_region(fg.region, box), new_age});
      }
    }
    res.boxes.push_back(out);
  }
  carried_ = std::move(next);
  for (std::size_t i = 0; i < fk.seen_support.size(); ++i) {
    res.num_on_support += fk.seen_support[i];
  }
  for (std::size_t i = 0; i < fk.seen_outside.size(); ++i) {
    res.num_outside_solid += fk.seen_outside[i];
  }
  return res;
}

}  // namespace ds3d
