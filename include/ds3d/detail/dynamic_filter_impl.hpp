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
#include <vector>

#include "ds3d/dynamic/dynamic_filter.hpp"

namespace ds3d {

inline void DynamicFilterParams::validate() const {
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

}  // namespace detail

inline DynamicFilterResult DynamicFeatureFilter::filter(
    Eigen::Ref<const Keypoints3f> keypoints, const std::vector<ImageBox>& boxes,
    const PinholeCamera& camera, const std::optional<Eigen::Vector4f>& support_plane) {
  constexpr const char* f = "ds3d::DynamicFeatureFilter::filter";
  camera.validate(f);
  std::optional<Eigen::Vector4f> plane;
  if (support_plane) plane = detail::unit_plane(*support_plane, f, "support_plane");
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

  const auto n = static_cast<std::size_t>(keypoints.rows());
  DynamicFilterResult res;
  res.dynamic.assign(n, 0);
  res.gated.assign(n, 0);
  std::vector<std::uint8_t> finite_uv(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    finite_uv[i] = std::isfinite(keypoints(r, 0)) && std::isfinite(keypoints(r, 1)) ? 1 : 0;
    if (finite_uv[i] == 0U) ++res.num_non_finite;
  }

  const auto sigma = [&](float z) { return params_.depth_noise * z * z; };
  const auto gap_at = [&](float z) { return params_.depth_gap + 3.0F * sigma(z); };

  const float img_u1 = static_cast<float>(camera.width) - 0.5F;
  const float img_v1 = static_cast<float>(camera.height) - 0.5F;

  // Boxes to process: detections (grown, clipped), then carried regions no detection covers.
  std::vector<std::pair<ImageBox, int>> work;  // box, age (-1 = detection)
  for (const ImageBox& x : boxes) {
    if (x.score < params_.min_score) {
      ++res.num_ignored_boxes;
      continue;
    }
    ImageBox g = x;
    const float mu = params_.box_margin * x.width();
    const float mv = params_.box_margin * x.height();
    g.x_min = std::max(x.x_min - mu, -0.5F);
    g.y_min = std::max(x.y_min - mv, -0.5F);
    g.x_max = std::min(x.x_max + mu, img_u1);
    g.y_max = std::min(x.y_max + mv, img_v1);
    if (!(g.x_max > g.x_min) || !(g.y_max > g.y_min)) {
      ++res.num_ignored_boxes;
      continue;
    }
    work.emplace_back(g, -1);
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

  // Metric gates (solids, support plane) need each depth keypoint's ray ∂p/∂z = (x/z, y/z, 1),
  // undistorted: computed once per frame, only when a gate is in use.
  const bool any_solid = std::any_of(work.begin(), work.end(),
                                     [](const auto& w) { return w.first.solid.has_value(); });
  std::vector<Eigen::Vector3f> ray;
  std::vector<std::uint8_t> on_support;
  if (any_solid || plane) {
    ray.assign(n, Eigen::Vector3f::Zero());
    on_support.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      if (finite_uv[i] == 0U || !detail::valid_depth(keypoints(r, 2))) continue;
      const Eigen::Vector2d xn = camera.undistort(
          {(keypoints(r, 0) - camera.cx) / camera.fx, (keypoints(r, 1) - camera.cy) / camera.fy});
      ray[i] = Eigen::Vector3f(static_cast<float>(xn.x()), static_cast<float>(xn.y()), 1.0F);
      if (plane) {
        const float z = keypoints(r, 2);
        on_support[i] =
            detail::near_plane(*plane, ray[i] * z, ray[i], sigma(z), params_.support_margin) ? 1
                                                                                             : 0;
      }
    }
  }
  std::vector<std::uint8_t> seen_support(on_support.empty() ? 0 : n, 0);
  std::vector<std::uint8_t> seen_outside(any_solid ? n : 0, 0);

  std::vector<Carried> next;
  std::vector<std::size_t> in_box;
  std::vector<std::size_t> with_depth;
  std::vector<std::int32_t> labels;
  for (const auto& [box, age] : work) {
    BoxOutcome out;
    out.box = box;
    out.carried = age >= 0;
    in_box.clear();
    with_depth.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      if (finite_uv[i] == 0U || !box.contains(keypoints(r, 0), keypoints(r, 1))) continue;
      in_box.push_back(i);
      const float z = keypoints(r, 2);
      if (!detail::valid_depth(z)) continue;
      // A depth range (3-D box or carried region) excludes everything outside it outright.
      if (box.has_depth_range() &&
          (z < box.z_min - 3.0F * sigma(box.z_min) || z > box.z_max + 3.0F * sigma(box.z_max))) {
        continue;
      }
      // Floor texture is static, whichever box it falls in.
      if (!on_support.empty() && on_support[i] != 0U) {
        seen_support[i] = 1;
        continue;
      }
      // An oriented 3-D box gates in 3-D: the rectangle and depth range of its projection also
      // hold the floor and furniture beside and below the object.
      if (box.solid && !box.solid->contains(ray[i] * z, ray[i], sigma(z))) {
        seen_outside[i] = 1;
        continue;
      }
      with_depth.push_back(i);
      res.gated[i] = 1;
    }
    out.num_keypoints = static_cast<int>(in_box.size());
    out.num_with_depth = static_cast<int>(with_depth.size());
    const auto kz = [&](std::size_t i) { return keypoints(static_cast<Eigen::Index>(i), 2); };
    const auto ku = [&](std::size_t i) { return keypoints(static_cast<Eigen::Index>(i), 0); };
    const auto kv = [&](std::size_t i) { return keypoints(static_cast<Eigen::Index>(i), 1); };

    detail::Region fg;                 // union of the dynamic clusters
    std::vector<std::uint8_t> member;  // per with_depth entry: 1 = in a dynamic cluster
    std::vector<std::uint8_t> noise;   // per with_depth entry: 1 = HDBSCAN noise
    member.assign(with_depth.size(), 0);
    noise.assign(with_depth.size(), 0);
    bool use_fallback = with_depth.size() < static_cast<std::size_t>(params_.min_keypoints);
    if (!use_fallback) {
      std::vector<float> zs(with_depth.size());
      for (std::size_t k = 0; k < with_depth.size(); ++k) zs[k] = kz(with_depth[k]);
      const double zmed = detail::median_of(zs);
      RowMatrixXd pts(static_cast<Eigen::Index>(with_depth.size()), 3);
      for (std::size_t k = 0; k < with_depth.size(); ++k) {
        const auto r = static_cast<Eigen::Index>(k);
        pts(r, 0) = ku(with_depth[k]);
        pts(r, 1) = kv(with_depth[k]);
        pts(r, 2) = kz(with_depth[k]);
      }
      HdbscanParams hp;
      hp.min_cluster_size = params_.min_cluster_size;
      hp.min_samples = params_.min_samples;
      // Pixels → metres at the median depth: clustering becomes isotropic in metric space.
      const HdbscanResult h = hdbscan(pts, hp, {zmed / camera.fx, zmed / camera.fy, 1.0});
      out.num_clusters = h.num_clusters;
      labels = h.labels;
      if (h.num_clusters == 0) {
        use_fallback = true;
      } else {
        const auto nc = static_cast<std::size_t>(h.num_clusters);
        std::vector<std::vector<float>> cz(nc);
        std::vector<detail::Region> cr(nc);
        for (std::size_t k = 0; k < with_depth.size(); ++k) {
          if (labels[k] < 0) {
            noise[k] = 1;
            continue;
          }
          const auto c = static_cast<std::size_t>(labels[k]);
          cz[c].push_back(kz(with_depth[k]));
          cr[c].add(ku(with_depth[k]), kv(with_depth[k]), kz(with_depth[k]));
        }
        std::vector<float> med(nc);
        for (std::size_t c = 0; c < nc; ++c) med[c] = detail::median_of(cz[c]);
        // Depth-continuous groups of clusters: in order of nearest depth, a cluster joins the
        // current group while its depth range [z0, z1] touches the group's (its near end within
        // gap + 3σ of the group's far end) and its median lies within max_object_depth of the
        // group's near end. A body that HDBSCAN splits into torso, arms and legs at different
        // depths is one chain; the background seen around or through it is not (it lies a gap
        // behind). The foreground is the shallowest group that spans enough of the box height (a
        // detected object fills its box; an occluder in front of part of it does not); if none
        // does, the shallowest group.
        std::vector<std::size_t> by_depth(nc);
        std::iota(by_depth.begin(), by_depth.end(), std::size_t{0});
        std::sort(by_depth.begin(), by_depth.end(), [&](std::size_t a, std::size_t b) {
          return cr[a].z0 < cr[b].z0 || (cr[a].z0 == cr[b].z0 && a < b);
        });
        std::vector<std::pair<std::size_t, std::size_t>> groups;  // [begin, end) in by_depth
        for (std::size_t g0 = 0; g0 < nc;) {
          std::size_t g1 = g0 + 1;
          float far = cr[by_depth[g0]].z1;
          while (g1 < nc && cr[by_depth[g1]].z0 - far <= gap_at(far) &&
                 med[by_depth[g1]] - cr[by_depth[g0]].z0 <= params_.max_object_depth) {
            far = std::max(far, cr[by_depth[g1]].z1);
            ++g1;
          }
          groups.emplace_back(g0, g1);
          g0 = g1;
        }
        const float need = params_.min_vertical_span * box.height();
        std::size_t chosen = 0;
        for (std::size_t g = 0; g < groups.size(); ++g) {
          float v0 = std::numeric_limits<float>::infinity();
          float v1 = -v0;
          for (std::size_t q = groups[g].first; q < groups[g].second; ++q) {
            v0 = std::min(v0, cr[by_depth[q]].v0);
            v1 = std::max(v1, cr[by_depth[q]].v1);
          }
          if (v1 - v0 >= need) {
            chosen = g;
            break;
          }
        }
        std::vector<std::uint8_t> dyn_cluster(nc, 0);
        for (std::size_t q = groups[chosen].first; q < groups[chosen].second; ++q) {
          const std::size_t c = by_depth[q];
          dyn_cluster[c] = 1;
          fg.u0 = std::min(fg.u0, cr[c].u0);
          fg.u1 = std::max(fg.u1, cr[c].u1);
          fg.v0 = std::min(fg.v0, cr[c].v0);
          fg.v1 = std::max(fg.v1, cr[c].v1);
          fg.z0 = std::min(fg.z0, cr[c].z0);
          fg.z1 = std::max(fg.z1, cr[c].z1);
        }
        for (std::size_t k = 0; k < with_depth.size(); ++k) {
          if (labels[k] >= 0 && dyn_cluster[static_cast<std::size_t>(labels[k])] != 0U) {
            member[k] = 1;
          }
        }
      }
    }
    if (use_fallback && !with_depth.empty()) {
      // Depth-gap split: sorted depths; groups end at gaps wider than gap + 3σ. The foreground is
      // the first group holding at least a fifth of the points (or min_samples), so that a stray
      // flying pixel in front does not become "the object".
      std::vector<std::size_t> order(with_depth.size());
      std::iota(order.begin(), order.end(), std::size_t{0});
      std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        const float za = kz(with_depth[a]);
        const float zb = kz(with_depth[b]);
        return za < zb || (za == zb && a < b);
      });
      const std::size_t need = std::min(
          order.size(), std::max<std::size_t>(static_cast<std::size_t>(params_.min_samples),
                                              (order.size() + 4) / 5));
      std::size_t begin = 0;
      while (begin < order.size()) {
        std::size_t end = begin + 1;
        while (end < order.size() && kz(with_depth[order[end]]) - kz(with_depth[order[end - 1]]) <=
                                         gap_at(kz(with_depth[order[end - 1]]))) {
          ++end;
        }
        if (end - begin >= need || end == order.size()) {
          for (std::size_t k = begin; k < end; ++k) {
            member[order[k]] = 1;
            const std::size_t i = with_depth[order[k]];
            fg.add(ku(i), kv(i), kz(i));
          }
          break;
        }
        begin = end;
      }
      std::fill(noise.begin(), noise.end(), 0);
      out.fallback = true;
    }

    // Mark: dynamic clusters; noise in the foreground's depth range and, unless the box has its
    // own depth range (then box + range already gate in 3-D), in its rectangle; keypoints
    // without depth in the rectangle (or anywhere in the box when no depth was seen at all).
    int marked = 0;
    const auto mark = [&](std::size_t i) {
      if (res.dynamic[i] == 0U) {
        res.dynamic[i] = 1;
        ++res.num_dynamic;
      }
      ++marked;
    };
    for (std::size_t k = 0; k < with_depth.size(); ++k) {
      const std::size_t i = with_depth[k];
      if (member[k] != 0U) {
        mark(i);
      } else if (noise[k] != 0U && !fg.empty() &&
                 (box.has_depth_range() || fg.contains(ku(i), kv(i))) &&
                 kz(i) >= fg.z0 - 3.0F * sigma(fg.z0) && kz(i) <= fg.z1 + 3.0F * sigma(fg.z1)) {
        mark(i);
      }
    }
    const bool saw_depth = out.num_with_depth > 0;
    for (const std::size_t i : in_box) {
      if (detail::valid_depth(kz(i))) continue;
      if ((!saw_depth && !box.has_depth_range()) || (!fg.empty() && fg.contains(ku(i), kv(i)))) {
        mark(i);
      }
    }
    out.num_dynamic = marked;
    if (!fg.empty()) {
      out.z_front = fg.z0;
      out.z_back = fg.z1;
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
      const int new_age = age < 0 ? 0 : age + 1;
      if (new_age < params_.carry_frames) next.push_back({region, new_age});
    }
    res.boxes.push_back(out);
  }
  carried_ = std::move(next);
  for (std::size_t i = 0; i < seen_support.size(); ++i) res.num_on_support += seen_support[i];
  for (std::size_t i = 0; i < seen_outside.size(); ++i) res.num_outside_solid += seen_outside[i];
  return res;
}

}  // namespace ds3d
