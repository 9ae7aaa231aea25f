// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Internals of the synthetic RGB-D generator shared by src/slam/synth*.cpp: meshes, humans, the
// scene state and the small helpers the scene, humanoid and rendering code all use. Not API.

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "ds3d/slam/synth.hpp"

namespace ds3d::synth {

inline constexpr double kPi = std::numbers::pi;
inline constexpr float kNear = 0.05F;
inline constexpr int kTex = 256;  // texture size (power of two: wrap with a mask)
inline constexpr std::uint8_t kNumParts = 10;

// Counter-based hash (SplitMix64): per-frame, per-pixel random numbers independent of order.
inline std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27U)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31U);
}

// High-contrast random texture: rectangles, discs and lines over a base colour, plus grain.
cv::Mat make_texture(std::mt19937_64& rng, const cv::Scalar& base, int shapes, int min_size,
                     int max_size);
// Two-colour cloth: stripes or checks, plus grain.
cv::Mat make_cloth(std::mt19937_64& rng);

struct Mesh {
  std::vector<Eigen::Vector3f> pos;  // world
  std::vector<Eigen::Vector2f> uv;   // texels
  std::vector<std::array<std::uint32_t, 3>> tris;
  int material = 0;
  std::uint8_t human = 0;  // 0 static, k+1
  std::uint8_t part = 0;   // 0 static, 1..10
};

inline void add_quad(Mesh& m, const Eigen::Vector3f& o, const Eigen::Vector3f& e1,
                     const Eigen::Vector3f& e2, float density) {
  const auto base = static_cast<std::uint32_t>(m.pos.size());
  const float l1 = e1.norm() * density;
  const float l2 = e2.norm() * density;
  m.pos.insert(m.pos.end(), {o, o + e1, o + e1 + e2, o + e2});
  m.uv.insert(m.uv.end(), {{0, 0}, {l1, 0}, {l1, l2}, {0, l2}});
  m.tris.push_back({base, base + 1, base + 2});
  m.tris.push_back({base, base + 2, base + 3});
}

// Axis-aligned box (world), every face textured.
inline void add_box(Mesh& m, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, float density) {
  const Eigen::Vector3f d = hi - lo;
  const Eigen::Vector3f ex(d.x(), 0, 0);
  const Eigen::Vector3f ey(0, d.y(), 0);
  const Eigen::Vector3f ez(0, 0, d.z());
  add_quad(m, lo, ex, ey, density);
  add_quad(m, lo + ez, ex, ey, density);
  add_quad(m, lo, ex, ez, density);
  add_quad(m, lo + ey, ex, ez, density);
  add_quad(m, lo, ey, ez, density);
  add_quad(m, lo + ex, ey, ez, density);
}

// Capsule from a to b (radius r) or, with axes, an ellipsoid: a UV sphere whose upper half is
// shifted by the segment length. Ellipsoid: centre a, semi-axes (sx, sy, sz) in frame `rot`.
inline void add_round(Mesh& m, const Eigen::Vector3f& a, const Eigen::Matrix3f& rot, float len,
                      const Eigen::Vector3f& semi, float density) {
  constexpr int kLon = 14;
  constexpr int kLat = 8;  // even
  const auto base = static_cast<std::uint32_t>(m.pos.size());
  // Rings from the bottom pole to the top pole; the equator ring appears twice, the second
  // copy shifted by len (a capsule's cylinder; none for an ellipsoid).
  int rings = 0;
  for (int k = 0; k <= kLat + 1; ++k) {
    const int kk = k <= kLat / 2 ? k : k - 1;
    const float shift = k <= kLat / 2 ? 0.0F : len;
    const float lat =
        -static_cast<float>(kPi) / 2 + static_cast<float>(kk) * static_cast<float>(kPi) / kLat;
    for (int j = 0; j <= kLon; ++j) {
      const float lon = 2 * static_cast<float>(kPi) * static_cast<float>(j) / kLon;
      const Eigen::Vector3f local(semi.x() * std::cos(lat) * std::cos(lon),
                                  semi.y() * std::cos(lat) * std::sin(lon),
                                  semi.z() * std::sin(lat) + shift);
      m.pos.push_back(a + rot * local);
      m.uv.emplace_back(lon * semi.x() * density, (semi.z() * std::sin(lat) + shift) * density);
    }
    ++rings;
  }
  for (int r = 0; r + 1 < rings; ++r) {
    for (int j = 0; j < kLon; ++j) {
      const auto i0 = base + static_cast<std::uint32_t>(r * (kLon + 1) + j);
      const auto i1 = i0 + 1;
      const auto i2 = i0 + static_cast<std::uint32_t>(kLon + 1);
      const auto i3 = i2 + 1;
      m.tris.push_back({i0, i1, i3});
      m.tris.push_back({i0, i3, i2});
    }
  }
}

// Frame whose z axis is `dir` (unit).
inline Eigen::Matrix3f frame_z(const Eigen::Vector3f& dir) {
  const Eigen::Vector3f z = dir.normalized();
  const Eigen::Vector3f helper =
      std::abs(z.x()) < 0.9F ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
  const Eigen::Vector3f x = helper.cross(z).normalized();
  Eigen::Matrix3f r;
  r.col(0) = x;
  r.col(1) = z.cross(x);
  r.col(2) = z;
  return r;
}

inline void add_capsule(Mesh& m, const Eigen::Vector3f& a, const Eigen::Vector3f& b, float r,
                        float density) {
  const Eigen::Vector3f d = b - a;
  add_round(m, a, frame_z(d), d.norm(), Eigen::Vector3f(r, r, r), density);
}

struct Human {
  double height = 1.75;
  double width = 1.0;  // girth factor
  bool sitting = false;
  Eigen::Vector2d a, b;  // walking: back and forth between a and b; sitting: seat at a
  double speed = 1.0;    // [m/s]
  double phase0 = 0;
  double yaw_sit = 0;
  int mat_shirt = 0, mat_pants = 0, mat_skin = 0;
  // Crowd scenarios: a closed route; the human starts at route[0] at t = 0, stands there for
  // dwell seconds (turning towards the next leg), walks to the next waypoint at `speed`, ...
  struct Waypoint {
    Eigen::Vector2d xy;
    double dwell = 0;  // [s]
    // Heading [rad] kept for the first 70 % of the dwell (NaN: turn all along from the heading
    // it came in with).
    double face = std::numeric_limits<double>::quiet_NaN();
  };
  std::vector<Waypoint> route;
  int carried = 0;  // 0 nothing, 1 board, 2 box, 3 bag
  int mat_carried = 0;
};

struct Pose2 {
  Eigen::Vector2d xy;
  double yaw;
  double gait;  // gait phase [rad]
};

struct SyntheticScene::Impl {
  SynthOptions opt;
  std::vector<cv::Mat> textures;
  std::vector<Mesh> static_meshes;
  std::vector<Human> humans;
  std::uint64_t noise_seed = 0;
  Eigen::Vector3d light = Eigen::Vector3d(0.3, 0.5, 0.8).normalized();

  [[nodiscard]] bool moving_camera_xyz() const {
    return opt.scenario == Scenario::kWalkingXyz || opt.scenario == Scenario::kSittingXyz ||
           opt.scenario == Scenario::kStaticRoom;
  }

  // ---- scene: room, furniture, textures, humans, camera path (synth_scene.cpp) ------------
  Eigen::Isometry3d camera_pose(double t_abs) const;
  void build(std::mt19937_64& rng);
  // Distance [m] on the floor from p to the nearest walker path or seat.
  [[nodiscard]] double distance_to_humans(const Eigen::Vector2d& p) const;
  // opt.extra_furniture chairs, tables and floor lamps, from a random stream of their own.
  void add_clutter(double room_x, double room_y);

  // ---- crowd scenarios (synth_crowd.cpp) -----------------------------------------------------
  // Camera shake knots (random walk, 10 Hz): rotation vector and translation in the camera frame.
  std::vector<Eigen::Matrix<double, 6, 1>> shake;
  std::vector<double> path;  // smooth path: sign and period factor per axis
  [[nodiscard]] bool crowd() const { return is_crowd(opt.scenario); }
  void build_crowd();  // people, routes, carried objects and shake, from their own stream
  [[nodiscard]] Eigen::Isometry3d crowd_motion(double t) const;  // relative to the base pose
  [[nodiscard]] Pose2 route_pose(const Human& h, double t) const;
  void carried_mesh(std::size_t k, const Pose2& p, std::vector<Mesh>& out) const;
  // Directional box blur of f.rgb along the mean image motion of the camera over one frame.
  void motion_blur(SynthFrame& f) const;

  // ---- humanoids: gait, body meshes, boxes (synth_humanoid.cpp) ---------------------------
  Pose2 human_pose(const Human& h, double t) const;
  // Builds the meshes of human k at time t (world coordinates).
  void human_meshes(std::size_t k, double t, std::vector<Mesh>& out) const;
  HumanBox box_of(std::size_t k, double t, const std::vector<Mesh>& meshes) const;

  // ---- rasteriser, colour and depth (synth_render.cpp) -------------------------------------
  struct Buffers {
    cv::Mat zbuf;   // CV_32F, +inf = empty
    cv::Mat color;  // CV_8UC3
    cv::Mat human;  // CV_8U
    cv::Mat part;   // CV_8U
  };

  struct CVert {
    Eigen::Vector3f p;  // camera frame
    Eigen::Vector2f uv;
  };

  void draw_triangle(const CVert* v, const cv::Mat& tex, float shade, std::uint8_t human,
                     std::uint8_t part, Buffers& b) const;
  void draw_mesh(const Mesh& m, const Eigen::Isometry3f& T_cam_world, Buffers& b) const;
  SynthFrame render(std::size_t i) const;
};

}  // namespace ds3d::synth
