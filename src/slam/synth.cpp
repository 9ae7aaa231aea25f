// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/synth.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/detail/json.hpp"
#include "ds3d/detail/tum_text.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"

namespace ds3d::synth {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr float kNear = 0.05F;
constexpr int kTex = 256;  // texture size (power of two: wrap with a mask)
constexpr std::uint8_t kNumParts = 10;

// Counter-based hash (SplitMix64): per-frame, per-pixel random numbers independent of order.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27U)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31U);
}

struct Mesh {
  std::vector<Eigen::Vector3f> pos;  // world
  std::vector<Eigen::Vector2f> uv;   // texels
  std::vector<std::array<std::uint32_t, 3>> tris;
  int material = 0;
  std::uint8_t human = 0;  // 0 static, k+1
  std::uint8_t part = 0;   // 0 static, 1..10
};

void add_quad(Mesh& m, const Eigen::Vector3f& o, const Eigen::Vector3f& e1,
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
void add_box(Mesh& m, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, float density) {
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
void add_round(Mesh& m, const Eigen::Vector3f& a, const Eigen::Matrix3f& rot, float len,
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
Eigen::Matrix3f frame_z(const Eigen::Vector3f& dir) {
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

void add_capsule(Mesh& m, const Eigen::Vector3f& a, const Eigen::Vector3f& b, float r,
                 float density) {
  const Eigen::Vector3f d = b - a;
  add_round(m, a, frame_z(d), d.norm(), Eigen::Vector3f(r, r, r), density);
}

// Adds uniform grain in [0, amplitude) to every texel, from a counter-based hash.
void add_grain(cv::Mat& tex, std::uint64_t seed, int amplitude) {
  for (int y = 0; y < tex.rows; ++y) {
    auto* row = tex.ptr<cv::Vec3b>(y);
    for (int x = 0; x < tex.cols; ++x) {
      const std::uint64_t h = mix(seed + static_cast<std::uint64_t>(y * tex.cols + x));
      for (int c = 0; c < 3; ++c) {
        const auto g =
            static_cast<int>((h >> (8U * static_cast<unsigned>(c))) & 0xFFU) * amplitude / 256;
        row[x][c] = cv::saturate_cast<std::uint8_t>(row[x][c] + g);
      }
    }
  }
}

// High-contrast random texture: rectangles, discs and lines over a base colour, plus grain.
cv::Mat make_texture(std::mt19937_64& rng, const cv::Scalar& base, int shapes, int min_size,
                     int max_size) {
  cv::Mat tex(kTex, kTex, CV_8UC3, base);
  std::uniform_int_distribution<int> pos(0, kTex - 1);
  std::uniform_int_distribution<int> sz(min_size, max_size);
  std::uniform_int_distribution<int> col(0, 255);
  for (int s = 0; s < shapes; ++s) {
    const cv::Scalar c(col(rng), col(rng), col(rng));
    const int x = pos(rng);
    const int y = pos(rng);
    const int w = sz(rng);
    const int h = sz(rng);
    // Draw at the wrapped copies too, so the texture tiles without seams.
    for (int dx : {-kTex, 0, kTex}) {
      for (int dy : {-kTex, 0, kTex}) {
        switch (s % 3) {
          case 0:
            cv::rectangle(tex, {x + dx, y + dy, w, h}, c, cv::FILLED);
            break;
          case 1:
            cv::circle(tex, {x + dx, y + dy}, w / 2, c, cv::FILLED);
            break;
          default:
            cv::line(tex, {x + dx, y + dy}, {x + dx + w, y + dy + h}, c, 2);
            break;
        }
      }
    }
  }
  add_grain(tex, rng(), 24);
  return tex;
}

cv::Mat make_cloth(std::mt19937_64& rng) {
  std::uniform_int_distribution<int> col(30, 230);
  const cv::Scalar a(col(rng), col(rng), col(rng));
  const cv::Scalar b(col(rng), col(rng), col(rng));
  cv::Mat tex(kTex, kTex, CV_8UC3, a);
  std::uniform_int_distribution<int> pattern(0, 2);
  const int p = pattern(rng);
  const int period = 16 << (rng() % 2);
  for (int y = 0; y < kTex; ++y) {
    for (int x = 0; x < kTex; ++x) {
      const bool on = p == 0   ? (y / period) % 2 == 0
                      : p == 1 ? ((x / period) + (y / period)) % 2 == 0
                               : ((x + y) / period) % 2 == 0;
      if (on)
        tex.at<cv::Vec3b>(y, x) =
            cv::Vec3b(static_cast<std::uint8_t>(b[0]), static_cast<std::uint8_t>(b[1]),
                      static_cast<std::uint8_t>(b[2]));
    }
  }
  add_grain(tex, rng(), 30);
  return tex;
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
};

struct Pose2 {
  Eigen::Vector2d xy;
  double yaw;
  double gait;  // gait phase [rad]
};

}  // namespace

// --------------------------------------------------------------------------------------------

Scenario parse_scenario(std::string_view name) {
  static const std::pair<std::string_view, Scenario> kNames[] = {
      {"static_room", Scenario::kStaticRoom}, {"walking_static", Scenario::kWalkingStatic},
      {"walking_xyz", Scenario::kWalkingXyz}, {"walking_halfsphere", Scenario::kWalkingHalfsphere},
      {"walking_rpy", Scenario::kWalkingRpy}, {"sitting_static", Scenario::kSittingStatic},
      {"sitting_xyz", Scenario::kSittingXyz}};
  for (const auto& [n, s] : kNames) {
    if (n == name) return s;
  }
  throw InvalidArgument(detail::concat(
      "ds3d::synth::parse_scenario: unknown scenario '", name,
      "' (valid: static_room, walking_static, walking_xyz, walking_halfsphere, walking_rpy, "
      "sitting_static, sitting_xyz)"));
}

std::string scenario_name(Scenario s) {
  switch (s) {
    case Scenario::kStaticRoom:
      return "static_room";
    case Scenario::kWalkingStatic:
      return "walking_static";
    case Scenario::kWalkingXyz:
      return "walking_xyz";
    case Scenario::kWalkingHalfsphere:
      return "walking_halfsphere";
    case Scenario::kWalkingRpy:
      return "walking_rpy";
    case Scenario::kSittingStatic:
      return "sitting_static";
    case Scenario::kSittingXyz:
      return "sitting_xyz";
  }
  return "unknown";
}

void SynthOptions::validate() const {
  constexpr const char* kFn = "ds3d::synth::SynthOptions";
  DS3D_CHECK(num_frames >= 1 && num_frames <= 100000, kFn,
             ": num_frames must be in [1, 100000] (got ", num_frames, ")");
  DS3D_CHECK(num_humans >= -1 && num_humans <= 4, kFn, ": num_humans must be in [0, 4] or -1 (got ",
             num_humans, ")");
  DS3D_CHECK(std::isfinite(fps) && fps > 0 && fps <= 1000, kFn, ": fps must be in (0, 1000] (got ",
             fps, ")");
  DS3D_CHECK(std::isfinite(start_time) && start_time >= 0, kFn,
             ": start_time must be finite and >= 0 (got ", start_time, ")");
  camera.validate(kFn);
  DS3D_CHECK(!camera.has_distortion(), kFn, ": camera must have no distortion");
  DS3D_CHECK(camera.width <= 8192 && camera.height <= 8192, kFn, ": image larger than 8192 px");
  DS3D_CHECK(room_size.allFinite() && room_size.x() >= 3.5 && room_size.x() <= 12 &&
                 room_size.y() >= 3 && room_size.y() <= 12 && room_size.z() >= 2.2 &&
                 room_size.z() <= 5,
             kFn, ": room_size must be in [3.5, 12] x [3, 12] x [2.2, 5] m (got ", room_size.x(),
             ", ", room_size.y(), ", ", room_size.z(), ")");
  DS3D_CHECK(extra_furniture >= 0 && extra_furniture <= 12, kFn,
             ": extra_furniture must be in [0, 12] (got ", extra_furniture, ")");
}

const std::vector<std::string>& part_names() {
  static const std::vector<std::string> kNames = {
      "static",          "torso",           "head",           "left_upper_arm", "left_lower_arm",
      "right_upper_arm", "right_lower_arm", "left_upper_leg", "left_lower_leg", "right_upper_leg",
      "right_lower_leg"};
  return kNames;
}

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

  Eigen::Isometry3d camera_pose(double t_abs) const {
    const double t = t_abs - opt.start_time;
    // Base: 0.5 m from the x = 0 wall, 1.4 m high, looking along +x (camera z) with image up = +z.
    Eigen::Matrix3d r_base;
    r_base.col(0) = Eigen::Vector3d(0, -1, 0);
    r_base.col(1) = Eigen::Vector3d(0, 0, -1);
    r_base.col(2) = Eigen::Vector3d(1, 0, 0);
    Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
    // Tilted 12 degrees down, like a hand-held Kinect looking at people and furniture.
    base.linear() = r_base * Eigen::AngleAxisd(-0.21, Eigen::Vector3d::UnitX()).toRotationMatrix();
    base.translation() = Eigen::Vector3d(0.5, opt.room_size.y() / 2, 1.4);
    // A hand-held wobble on every trajectory (mm, sub-degree).
    const Eigen::Vector3d wobble(0.004 * std::sin(2.1 * t), 0.003 * std::sin(1.7 * t + 1),
                                 0.004 * std::sin(1.3 * t + 2));
    Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
    const double w = 2 * kPi;
    switch (opt.scenario) {
      case Scenario::kWalkingStatic:
      case Scenario::kSittingStatic:
        motion.translation() = wobble;
        motion.linear() = Eigen::AngleAxisd(0.004 * std::sin(0.9 * t), Eigen::Vector3d::UnitY())
                              .toRotationMatrix();
        break;
      case Scenario::kWalkingXyz:
      case Scenario::kSittingXyz:
      case Scenario::kStaticRoom:
        motion.translation() =
            Eigen::Vector3d(0.35 * std::sin(w * t / 7.0), 0.2 * std::sin(w * t / 5.0),
                            0.3 * std::sin(w * t / 9.0)) +
            wobble;
        break;
      case Scenario::kWalkingRpy: {
        const double roll = 0.35 * std::sin(w * t / 6.0);
        const double pitch = 0.25 * std::sin(w * t / 8.0);
        const double yaw = 0.45 * std::sin(w * t / 10.0);
        motion.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) *
                           Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()) *
                           Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
                              .toRotationMatrix();
        motion.translation() = wobble;
        break;
      }
      case Scenario::kWalkingHalfsphere: {
        // Camera on a sphere of radius 1 m around a point 1 m ahead, looking at it.
        const double az = 0.6 * std::sin(w * t / 12.0);
        const double el = 0.25 + 0.2 * std::sin(w * t / 9.0);
        const Eigen::Vector3d centre(1.5, opt.room_size.y() / 2, 1.2);
        const Eigen::Vector3d eye =
            centre + Eigen::Vector3d(-std::cos(el) * std::cos(az), -std::cos(el) * std::sin(az),
                                     std::sin(el));
        const Eigen::Vector3d z = (centre - eye).normalized();
        const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
        Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
        p.linear().col(0) = x;
        p.linear().col(1) = z.cross(x);
        p.linear().col(2) = z;
        p.translation() = eye + wobble;
        return p;
      }
    }
    return base * motion;
  }

  Pose2 human_pose(const Human& h, double t) const {
    if (h.sitting) return {h.a, h.yaw_sit, 0.0};
    const Eigen::Vector2d d = h.b - h.a;
    const double len = d.norm();
    const double s = h.speed * t + h.phase0 * len;
    const double cyc = std::fmod(s, 2 * len);
    const bool back = cyc > len;
    const double along = back ? 2 * len - cyc : cyc;
    const Eigen::Vector2d dir = (back ? -d : d) / len;
    const double stride = 0.75 * h.height;  // one gait cycle = two steps
    return {h.a + d * (along / len), std::atan2(dir.y(), dir.x()), 2 * kPi * s / stride};
  }

  // Builds the meshes of human k at time t (world coordinates).
  void human_meshes(std::size_t k, double t, std::vector<Mesh>& out) const {
    const Human& h = humans[k];
    const Pose2 p = human_pose(h, t);
    const auto H = static_cast<float>(h.height);
    const float s = H / 1.75F;
    const auto g = static_cast<float>(h.width);
    const float leg1 = 0.245F * H;
    const float leg2 = 0.25F * H;
    const float arm1 = 0.17F * H;
    const float arm2 = 0.16F * H;
    const float phi = static_cast<float>(p.gait);
    float hip_z = leg1 + leg2 + 0.02F * s;
    float bob = 0;
    std::array<float, 2> thigh{}, knee{}, shoulder{}, elbow{};
    float lean = 0;
    float head_yaw = 0;
    if (h.sitting) {
      hip_z = leg2 + 0.06F * s;
      const float tt = static_cast<float>(t);
      const auto ph0 = static_cast<float>(h.phase0 * 2 * kPi);
      for (int side = 0; side < 2; ++side) {
        thigh[side] = -static_cast<float>(kPi) / 2;
        knee[side] = static_cast<float>(kPi) / 2 - 0.15F;
        shoulder[side] =
            -0.25F - 0.35F * std::sin(0.9F * tt + 1.7F * static_cast<float>(side) + ph0);
        elbow[side] = -0.9F - 0.5F * std::sin(1.3F * tt + static_cast<float>(side));
      }
      lean = 0.08F * std::sin(0.5F * tt + ph0);
      head_yaw = 0.4F * std::sin(0.7F * tt);
    } else {
      bob = 0.015F * s * std::abs(std::sin(phi));
      for (int side = 0; side < 2; ++side) {
        const float ph = phi + static_cast<float>(side) * static_cast<float>(kPi);
        thigh[side] = -0.42F * std::sin(ph);
        knee[side] = 0.55F * std::max(0.0F, std::sin(ph - 0.6F)) + 0.05F;
        shoulder[side] = 0.38F * std::sin(ph);
        elbow[side] = -0.35F - 0.2F * std::max(0.0F, -std::sin(ph));
      }
    }
    // Local frame: x forward, y left, z up, origin on the floor under the hips.
    const Eigen::Matrix3f yaw =
        Eigen::AngleAxisf(static_cast<float>(p.yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix();
    const Eigen::Vector3f origin(static_cast<float>(p.xy.x()), static_cast<float>(p.xy.y()), 0);
    const auto W = [&](const Eigen::Vector3f& local) -> Eigen::Vector3f {
      return origin + yaw * local;
    };
    const auto down = [](float a) {  // (0,0,-1) rotated by a about y: + moves it backwards (-x)
      return Eigen::Vector3f(-std::sin(a), 0, -std::cos(a));
    };
    // Seated, the torso drops by the difference of hip heights.
    const float shoulder_z = 0.815F * H + (hip_z - (leg1 + leg2 + 0.02F * s)) + bob;
    const float hip_zb = hip_z + bob;
    const auto add_part = [&](std::uint8_t part, int mat, auto&& build) {
      Mesh m;
      m.material = mat;
      m.human = static_cast<std::uint8_t>(k + 1);
      m.part = part;
      build(m);
      out.push_back(std::move(m));
    };
    const float density = 400.0F;
    // torso: ellipsoid between hips and shoulders, leaning forward a little
    const Eigen::Vector3f torso_c(lean * 0.15F, 0, 0.5F * (hip_zb + shoulder_z));
    const Eigen::Matrix3f torso_r =
        yaw * Eigen::AngleAxisf(lean, Eigen::Vector3f::UnitY()).toRotationMatrix();
    add_part(1, h.mat_shirt, [&](Mesh& m) {
      add_round(
          m, W(torso_c), torso_r, 0.0F,
          Eigen::Vector3f(0.12F * s * g, 0.19F * s * g, 0.5F * (shoulder_z - hip_zb) + 0.05F * s),
          density);
    });
    const Eigen::Matrix3f head_r =
        yaw * Eigen::AngleAxisf(head_yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    add_part(2, h.mat_skin, [&](Mesh& m) {
      add_round(m, W(Eigen::Vector3f(lean * 0.3F, 0, shoulder_z + 0.13F * s)), head_r, 0.0F,
                Eigen::Vector3f(0.085F * s, 0.075F * s, 0.11F * s), density);
    });
    for (int side = 0; side < 2; ++side) {
      const float y = side == 0 ? 1.0F : -1.0F;
      const auto side_u = static_cast<std::uint8_t>(side * 2);
      // arms (upper arm swings about y; the elbow bends the forearm forwards)
      const Eigen::Vector3f sh(lean * 0.3F, y * 0.2F * s * g, shoulder_z - 0.03F * s);
      const Eigen::Vector3f el = sh + arm1 * down(shoulder[side]);
      const Eigen::Vector3f wr = el + arm2 * down(shoulder[side] + elbow[side]);
      add_part(static_cast<std::uint8_t>(3 + side_u), h.mat_shirt,
               [&](Mesh& m) { add_capsule(m, W(sh), W(el), 0.05F * s * g, density); });
      add_part(static_cast<std::uint8_t>(4 + side_u), h.mat_skin,
               [&](Mesh& m) { add_capsule(m, W(el), W(wr), 0.04F * s, density); });
      // legs
      const Eigen::Vector3f hp(0, y * 0.09F * s * g, hip_zb);
      const Eigen::Vector3f kn = hp + leg1 * down(thigh[side]);
      const Eigen::Vector3f an = kn + leg2 * down(thigh[side] + knee[side]);
      add_part(static_cast<std::uint8_t>(7 + side_u), h.mat_pants,
               [&](Mesh& m) { add_capsule(m, W(hp), W(kn), 0.075F * s * g, density); });
      add_part(static_cast<std::uint8_t>(8 + side_u), h.mat_pants,
               [&](Mesh& m) { add_capsule(m, W(kn), W(an), 0.055F * s * g, density); });
    }
  }

  HumanBox box_of(std::size_t k, double t, const std::vector<Mesh>& meshes) const {
    const Pose2 p = human_pose(humans[k], t);
    const Eigen::Matrix3d yaw_r =
        Eigen::AngleAxisd(p.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9);
    Eigen::Vector3d hi = Eigen::Vector3d::Constant(-1e9);
    const Eigen::Vector3d origin(p.xy.x(), p.xy.y(), 0);
    for (const Mesh& m : meshes) {
      if (m.human != k + 1) continue;
      for (const auto& v : m.pos) {
        const Eigen::Vector3d local = yaw_r.transpose() * (v.cast<double>() - origin);
        lo = lo.cwiseMin(local);
        hi = hi.cwiseMax(local);
      }
    }
    HumanBox b;
    b.id = static_cast<int>(k);
    b.center = origin + yaw_r * (0.5 * (lo + hi));
    b.size = hi - lo;
    b.yaw = p.yaw;
    b.sitting = humans[k].sitting;
    return b;
  }

  void build(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> u01(0, 1);
    const auto uni = [&](double a, double b) { return a + (b - a) * u01(rng); };
    noise_seed = rng();
    // Textures: 0 floor, 1-4 walls, 5 ceiling, 6.. furniture, then clothes/skin.
    const auto base_col = [&] { return cv::Scalar(uni(60, 200), uni(60, 200), uni(60, 200)); };
    textures.push_back(make_texture(rng, base_col(), 140, 6, 40));  // floor
    for (int w = 0; w < 4; ++w) textures.push_back(make_texture(rng, base_col(), 110, 8, 60));
    textures.push_back(make_texture(rng, cv::Scalar(200, 200, 200), 40, 10, 60));  // ceiling
    const int first_furniture = static_cast<int>(textures.size());
    for (int f = 0; f < 6; ++f) textures.push_back(make_texture(rng, base_col(), 120, 4, 30));

    const double room_x = opt.room_size.x();
    const double room_y = opt.room_size.y();
    const auto X = static_cast<float>(room_x);
    const auto Y = static_cast<float>(room_y);
    const auto Z = static_cast<float>(opt.room_size.z());
    const auto quad_mesh = [&](int mat, const Eigen::Vector3f& o, const Eigen::Vector3f& e1,
                               const Eigen::Vector3f& e2, float density) {
      Mesh m;
      m.material = mat;
      add_quad(m, o, e1, e2, density);
      static_meshes.push_back(std::move(m));
    };
    quad_mesh(0, {0, 0, 0}, {X, 0, 0}, {0, Y, 0}, 110.0F);
    quad_mesh(1, {X, 0, 0}, {0, Y, 0}, {0, 0, Z}, 90.0F);
    quad_mesh(2, {0, 0, 0}, {X, 0, 0}, {0, 0, Z}, 90.0F);
    quad_mesh(3, {0, Y, 0}, {X, 0, 0}, {0, 0, Z}, 90.0F);
    quad_mesh(4, {0, 0, 0}, {0, Y, 0}, {0, 0, Z}, 90.0F);
    quad_mesh(5, {0, 0, Z}, {X, 0, 0}, {0, Y, 0}, 60.0F);

    // Furniture along the far wall and the side walls.
    for (int f = 0; f < 6; ++f) {
      Mesh m;
      m.material = first_furniture + f;
      const double w = uni(0.4, 1.1);
      const double d = uni(0.35, 0.7);
      const double hgt = uni(0.45, 1.9);
      Eigen::Vector3d lo;
      if (f < 3) {  // far wall
        lo = Eigen::Vector3d(room_x - d - 0.02, 0.3 + f * 1.5 * (room_y / 5.0) + uni(0, 0.4), 0);
        add_box(m, lo.cast<float>(), (lo + Eigen::Vector3d(d, w, hgt)).cast<float>(), 130.0F);
      } else {  // side walls, beyond x = 1.4 so they stay in view
        const bool left = f % 2 == 1;
        const double x0 = 1.4 + (f - 3) * 0.9 * (room_x / 4.5) + uni(0, 0.3);
        lo = Eigen::Vector3d(x0, left ? room_y - d - 0.02 : 0.02, 0);
        add_box(m, lo.cast<float>(), (lo + Eigen::Vector3d(w, d, hgt)).cast<float>(), 130.0F);
      }
      static_meshes.push_back(std::move(m));
    }

    // Humans.
    int n = opt.num_humans;
    if (n < 0) n = opt.scenario == Scenario::kStaticRoom ? 0 : 2;
    const bool sitting =
        opt.scenario == Scenario::kSittingStatic || opt.scenario == Scenario::kSittingXyz;
    for (int k = 0; k < n; ++k) {
      Human h;
      h.height = uni(1.55, 1.95);
      h.width = uni(0.85, 1.2);
      h.sitting = sitting;
      h.phase0 = uni(0, 1);
      h.mat_shirt = static_cast<int>(textures.size());
      textures.push_back(make_cloth(rng));
      h.mat_pants = static_cast<int>(textures.size());
      textures.push_back(make_cloth(rng));
      h.mat_skin = static_cast<int>(textures.size());
      textures.push_back(
          make_texture(rng, cv::Scalar(uni(60, 150), uni(90, 170), uni(140, 220)), 12, 4, 12));
      if (sitting) {
        // Seats spread across the view, 1.8-3.2 m ahead, facing the camera +- 30 deg.
        h.a = Eigen::Vector2d(uni(2.2, room_x - 1.1),
                              room_y / 2 + (k - (n - 1) / 2.0) * 1.0 + uni(-0.15, 0.15));
        h.yaw_sit = kPi + uni(-0.5, 0.5);
        Mesh seat;
        seat.material = first_furniture + (k % 6);
        const float leg2 = 0.25F * static_cast<float>(h.height);
        const float seat_h = leg2 + 0.06F * static_cast<float>(h.height / 1.75) -
                             0.075F * static_cast<float>(h.height / 1.75 * h.width);
        const Eigen::Vector2d c = h.a;
        add_box(
            seat,
            Eigen::Vector3f(static_cast<float>(c.x() - 0.22), static_cast<float>(c.y() - 0.22), 0),
            Eigen::Vector3f(static_cast<float>(c.x() + 0.22), static_cast<float>(c.y() + 0.22),
                            seat_h),
            150.0F);
        static_meshes.push_back(std::move(seat));
      } else {
        // Walk back and forth across the view, 1.5-3.5 m ahead.
        for (int tries = 0; tries < 100; ++tries) {
          h.a = Eigen::Vector2d(uni(1.5, room_x - 0.9), uni(0.9, room_y - 0.9));
          h.b = Eigen::Vector2d(uni(1.5, room_x - 0.9), uni(0.9, room_y - 0.9));
          if ((h.b - h.a).norm() > 1.8) break;
        }
        h.speed = uni(0.7, 1.3);
      }
      humans.push_back(h);
    }
    if (opt.extra_furniture > 0) add_clutter(room_x, room_y);
  }

  // Distance [m] on the floor from p to the nearest walker path or seat.
  [[nodiscard]] double distance_to_humans(const Eigen::Vector2d& p) const {
    double best = std::numeric_limits<double>::infinity();
    for (const Human& h : humans) {
      if (h.sitting) {
        best = std::min(best, (p - h.a).norm());
        continue;
      }
      const Eigen::Vector2d ab = h.b - h.a;
      const double s = std::clamp((p - h.a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
      best = std::min(best, (p - (h.a + s * ab)).norm());
    }
    return best;
  }

  // opt.extra_furniture chairs, tables and floor lamps, from a random stream of their own.
  void add_clutter(double room_x, double room_y) {
    std::mt19937_64 rng(mix(opt.seed ^ 0x5eed'c1a7'7e12'0001ULL));
    std::uniform_real_distribution<double> u01(0, 1);
    const auto uni = [&](double a, double b) { return a + (b - a) * u01(rng); };
    const auto box = [](Mesh& m, double x0, double y0, double z0, double x1, double y1, double z1) {
      add_box(
          m,
          Eigen::Vector3f(static_cast<float>(x0), static_cast<float>(y0), static_cast<float>(z0)),
          Eigen::Vector3f(static_cast<float>(x1), static_cast<float>(y1), static_cast<float>(z1)),
          150.0F);
    };
    std::vector<std::pair<Eigen::Vector2d, double>> placed;  // centre, radius
    for (int f = 0; f < opt.extra_furniture; ++f) {
      const int kind = static_cast<int>(u01(rng) * 3);  // 0 chair, 1 table, 2 floor lamp
      Mesh m;  // built around the origin, then turned and moved
      m.material = static_cast<int>(textures.size());
      textures.push_back(
          make_texture(rng, cv::Scalar(uni(40, 210), uni(40, 210), uni(40, 210)), 120, 4, 30));
      double radius = 0;
      if (kind == 0) {
        const double w = uni(0.40, 0.50);
        const double hs = uni(0.42, 0.50);
        const double hb = uni(0.35, 0.55);
        const double l = 0.035;
        for (const double sx : {-1.0, 1.0}) {
          for (const double sy : {-1.0, 1.0}) {
            const double cx = sx * (w / 2 - l);
            const double cy = sy * (w / 2 - l);
            box(m, cx - l / 2, cy - l / 2, 0, cx + l / 2, cy + l / 2, hs - 0.05);
          }
        }
        box(m, -w / 2, -w / 2, hs - 0.05, w / 2, w / 2, hs);
        box(m, -w / 2, -w / 2, hs, -w / 2 + 0.04, w / 2, hs + hb);
        radius = 0.75 * w;
      } else if (kind == 1) {
        const double a = uni(0.7, 1.6);
        const double b = uni(0.6, 0.9);
        const double h = uni(0.70, 0.78);
        const double l = 0.05;
        for (const double sx : {-1.0, 1.0}) {
          for (const double sy : {-1.0, 1.0}) {
            const double cx = sx * (a / 2 - l);
            const double cy = sy * (b / 2 - l);
            box(m, cx - l / 2, cy - l / 2, 0, cx + l / 2, cy + l / 2, h - 0.04);
          }
        }
        box(m, -a / 2, -b / 2, h - 0.04, a / 2, b / 2, h);
        radius = 0.5 * std::hypot(a, b);
      } else {
        const double h = uni(1.4, 1.8);
        box(m, -0.15, -0.15, 0, 0.15, 0.15, 0.03);
        box(m, -0.015, -0.015, 0.03, 0.015, 0.015, h - 0.25);
        box(m, -0.16, -0.16, h - 0.25, 0.16, 0.16, h);
        radius = 0.25;
      }
      // A free spot: inside the room, clear of the other clutter and 0.5 m from the people.
      bool found = false;
      Eigen::Vector2d c;
      for (int tries = 0; tries < 50 && !found; ++tries) {
        c = Eigen::Vector2d(uni(1.2, room_x - 0.3 - radius),
                            uni(0.3 + radius, room_y - 0.3 - radius));
        found = distance_to_humans(c) > 0.5 + radius;
        for (const auto& [q, r] : placed) found = found && (c - q).norm() > r + radius + 0.2;
      }
      if (!found) continue;
      placed.emplace_back(c, radius);
      const double yaw = uni(-kPi, kPi);
      const Eigen::Matrix3f rot =
          Eigen::AngleAxisf(static_cast<float>(yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix();
      const Eigen::Vector3f t(static_cast<float>(c.x()), static_cast<float>(c.y()), 0);
      for (auto& p : m.pos) p = rot * p + t;
      static_meshes.push_back(std::move(m));
    }
  }

  // ---- rasteriser --------------------------------------------------------------------------
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
                     std::uint8_t part, Buffers& b) const {
    const auto& c = opt.camera;
    const auto fx = static_cast<float>(c.fx);
    const auto fy = static_cast<float>(c.fy);
    const auto cx = static_cast<float>(c.cx);
    const auto cy = static_cast<float>(c.cy);
    float sx[3], sy[3], iz[3], uz[3], vz[3];
    for (int k = 0; k < 3; ++k) {
      iz[k] = 1.0F / v[k].p.z();
      sx[k] = fx * v[k].p.x() * iz[k] + cx;
      sy[k] = fy * v[k].p.y() * iz[k] + cy;
      uz[k] = v[k].uv.x() * iz[k];
      vz[k] = v[k].uv.y() * iz[k];
    }
    const float area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
    if (!(std::abs(area) > 1e-9F)) return;
    const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({sx[0], sx[1], sx[2]}))));
    const int x1 =
        std::min(c.width - 1, static_cast<int>(std::floor(std::max({sx[0], sx[1], sx[2]}))));
    const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({sy[0], sy[1], sy[2]}))));
    const int y1 =
        std::min(c.height - 1, static_cast<int>(std::floor(std::max({sy[0], sy[1], sy[2]}))));
    if (x0 > x1 || y0 > y1) return;
    const float inv_area = 1.0F / area;
    // Edge functions w_k(x, y) = A_k x + B_k y + C_k, normalised so that w0 + w1 + w2 = 1.
    float ea[3], eb[3], ec[3];
    for (int k = 0; k < 3; ++k) {
      const int i = (k + 1) % 3;
      const int j = (k + 2) % 3;
      ea[k] = (sy[i] - sy[j]) * inv_area;
      eb[k] = (sx[j] - sx[i]) * inv_area;
      ec[k] = (sx[i] * sy[j] - sx[j] * sy[i]) * inv_area;
    }
    const std::uint8_t s8 = static_cast<std::uint8_t>(std::clamp(shade * 256.0F, 0.0F, 255.0F));
    for (int y = y0; y <= y1; ++y) {
      auto* zrow = b.zbuf.ptr<float>(y);
      auto* crow = b.color.ptr<cv::Vec3b>(y);
      auto* hrow = b.human.ptr<std::uint8_t>(y);
      auto* prow = b.part.ptr<std::uint8_t>(y);
      const auto fyv = static_cast<float>(y);
      // Solve w_k(x) >= 0 for the span of this row instead of testing every pixel of the box.
      float lo = static_cast<float>(x0);
      float hi = static_cast<float>(x1);
      for (int k = 0; k < 3; ++k) {
        const float c0 = eb[k] * fyv + ec[k];
        if (ea[k] > 0) {
          lo = std::max(lo, -c0 / ea[k]);
        } else if (ea[k] < 0) {
          hi = std::min(hi, -c0 / ea[k]);
        } else if (c0 < 0) {
          hi = -1;
        }
      }
      if (!(lo <= hi)) continue;
      const int xa = std::max(x0, static_cast<int>(std::ceil(lo)));
      const int xb = std::min(x1, static_cast<int>(std::floor(hi)));
      for (int x = xa; x <= xb; ++x) {
        const auto fxv = static_cast<float>(x);
        const float w0 = ea[0] * fxv + eb[0] * fyv + ec[0];
        const float w1 = ea[1] * fxv + eb[1] * fyv + ec[1];
        const float w2 = 1.0F - w0 - w1;
        const float invz = w0 * iz[0] + w1 * iz[1] + w2 * iz[2];
        const float z = 1.0F / invz;
        if (!(z < zrow[x]) || z < kNear) continue;
        zrow[x] = z;
        const float u = (w0 * uz[0] + w1 * uz[1] + w2 * uz[2]) * z;
        const float vv = (w0 * vz[0] + w1 * vz[1] + w2 * vz[2]) * z;
        const int tu = static_cast<int>(std::floor(u)) & (kTex - 1);
        const int tv = static_cast<int>(std::floor(vv)) & (kTex - 1);
        const cv::Vec3b t = tex.at<cv::Vec3b>(tv, tu);
        crow[x] = cv::Vec3b(static_cast<std::uint8_t>((t[0] * s8) >> 8U),
                            static_cast<std::uint8_t>((t[1] * s8) >> 8U),
                            static_cast<std::uint8_t>((t[2] * s8) >> 8U));
        hrow[x] = human;
        prow[x] = part;
      }
    }
  }

  void draw_mesh(const Mesh& m, const Eigen::Isometry3f& T_cam_world, Buffers& b) const {
    std::vector<Eigen::Vector3f> pc(m.pos.size());
    for (std::size_t i = 0; i < m.pos.size(); ++i) pc[i] = T_cam_world * m.pos[i];
    const cv::Mat& tex = textures[static_cast<std::size_t>(m.material)];
    for (const auto& t : m.tris) {
      const Eigen::Vector3f& a = m.pos[t[0]];
      Eigen::Vector3f nrm = (m.pos[t[1]] - a).cross(m.pos[t[2]] - a);
      const float nn = nrm.norm();
      if (!(nn > 1e-12F)) continue;
      nrm /= nn;
      // Two-sided Lambert with ambient light.
      const float shade = 0.55F + 0.4F * std::abs(nrm.dot(light.cast<float>()));
      CVert in[3];
      int n_in = 0;
      for (int k = 0; k < 3; ++k) {
        in[k] = {pc[t[static_cast<std::size_t>(k)]], m.uv[t[static_cast<std::size_t>(k)]]};
        if (in[k].p.z() >= kNear) ++n_in;
      }
      if (n_in == 0) continue;
      if (n_in == 3) {
        draw_triangle(in, tex, shade, m.human, m.part, b);
        continue;
      }
      // Clip against z = near (Sutherland-Hodgman), then fan-triangulate.
      CVert poly[4];
      int np = 0;
      for (int k = 0; k < 3; ++k) {
        const CVert& p = in[k];
        const CVert& q = in[(k + 1) % 3];
        const bool pin = p.p.z() >= kNear;
        const bool qin = q.p.z() >= kNear;
        if (pin) poly[np++] = p;
        if (pin != qin) {
          const float s = (kNear - p.p.z()) / (q.p.z() - p.p.z());
          poly[np++] = {p.p + s * (q.p - p.p), p.uv + s * (q.uv - p.uv)};
        }
      }
      for (int k = 1; k + 1 < np; ++k) {
        const CVert tri[3] = {poly[0], poly[k], poly[k + 1]};
        draw_triangle(tri, tex, shade, m.human, m.part, b);
      }
    }
  }

  SynthFrame render(std::size_t i) const {
    const auto& cam = opt.camera;
    SynthFrame f;
    f.index = i;
    f.timestamp = opt.start_time + static_cast<double>(i) / opt.fps;
    const double t = static_cast<double>(i) / opt.fps;
    f.T_world_cam = camera_pose(f.timestamp);
    const Eigen::Isometry3f T_cw = f.T_world_cam.inverse().cast<float>();
    Buffers b;
    b.zbuf =
        cv::Mat(cam.height, cam.width, CV_32F, cv::Scalar(std::numeric_limits<float>::infinity()));
    b.color = cv::Mat(cam.height, cam.width, CV_8UC3, cv::Scalar(0, 0, 0));
    b.human = cv::Mat::zeros(cam.height, cam.width, CV_8U);
    b.part = cv::Mat::zeros(cam.height, cam.width, CV_8U);
    // Humans first: they are near, so the z-test rejects most room pixels behind them early.
    std::vector<Mesh> hm;
    for (std::size_t k = 0; k < humans.size(); ++k) human_meshes(k, t, hm);
    for (const Mesh& m : hm) draw_mesh(m, T_cw, b);
    for (const Mesh& m : static_meshes) draw_mesh(m, T_cw, b);
    for (std::size_t k = 0; k < humans.size(); ++k) f.boxes.push_back(box_of(k, t, hm));

    f.rgb = b.color;
    f.human_id = b.human;
    f.part_id = b.part;
    cv::compare(b.human, 0, f.dynamic_mask, cv::CMP_GT);
    f.depth_true = cv::Mat::zeros(cam.height, cam.width, CV_32F);
    f.depth = cv::Mat::zeros(cam.height, cam.width, CV_16U);
    const std::uint64_t frame_seed = mix(noise_seed ^ mix(i));
    const double baseline_fx = 0.075 * cam.fx;  // Kinect: 7.5 cm baseline
    for (int y = 0; y < cam.height; ++y) {
      const float* z = b.zbuf.ptr<float>(y);
      float* zt = f.depth_true.ptr<float>(y);
      std::uint16_t* d = f.depth.ptr<std::uint16_t>(y);
      const std::uint8_t* hrow = b.human.ptr<std::uint8_t>(y);
      cv::Vec3b* crow = f.rgb.ptr<cv::Vec3b>(y);
      for (int x = 0; x < cam.width; ++x) {
        if (!std::isfinite(z[x])) continue;
        zt[x] = z[x];
        if (hrow[x] > 0) ++f.boxes[hrow[x] - 1U].visible_pixels;
        const std::uint64_t h = mix(frame_seed + static_cast<std::uint64_t>(y) * 65536U +
                                    static_cast<std::uint64_t>(x));
        // Sensor grain on the colour image (+-3 levels).
        const int grain = static_cast<int>(h & 7U) - 3;
        for (int ch = 0; ch < 3; ++ch) {
          crow[x][ch] = cv::saturate_cast<std::uint8_t>(crow[x][ch] + grain);
        }
        double zz = z[x];
        if (opt.depth_noise) {
          if (zz > 4.5) continue;  // beyond the sensor's range: no depth
          // Hole at a depth discontinuity (the projector/camera shadow), most of the time.
          float jump = 0;
          if (x > 0 && std::isfinite(z[x - 1])) jump = std::max(jump, std::abs(z[x - 1] - z[x]));
          if (x + 1 < cam.width && std::isfinite(z[x + 1]))
            jump = std::max(jump, std::abs(z[x + 1] - z[x]));
          if (y > 0) {
            const float zu = b.zbuf.ptr<float>(y - 1)[x];
            if (std::isfinite(zu)) jump = std::max(jump, std::abs(zu - z[x]));
          }
          if (jump > 0.04F * z[x] && ((h >> 3U) & 0xFFU) < 205U) continue;  // 80 %
          // Gaussian noise, sigma = 1.425e-3 z^2: sum of four 12-bit uniforms (Irwin-Hall,
          // variance 4/12, rescaled), one hash per pixel instead of log/cos.
          const double sum4 = static_cast<double>(((h >> 12U) & 0xFFFU) + ((h >> 24U) & 0xFFFU) +
                                                  ((h >> 36U) & 0xFFFU) + ((h >> 48U) & 0xFFFU)) /
                              4096.0;
          const double gauss = (sum4 - 2.0) * 1.7320508075688772;
          zz += 1.425e-3 * zz * zz * gauss;
          // Disparity quantised to 1/8 pixel.
          const double disp = std::round(baseline_fx / zz * 8.0) / 8.0;
          if (disp <= 0) continue;
          zz = baseline_fx / disp;
        }
        const double units = std::round(zz * cam.depth_scale);
        if (units >= 1 && units <= 65535) d[x] = static_cast<std::uint16_t>(units);
      }
    }
    return f;
  }
};

SyntheticScene::SyntheticScene(const SynthOptions& options) : impl_(new Impl) {
  try {
    options.validate();
    impl_->opt = options;
    std::mt19937_64 rng(mix(options.seed));
    impl_->build(rng);
  } catch (...) {
    delete impl_;
    throw;
  }
}
SyntheticScene::~SyntheticScene() { delete impl_; }
SyntheticScene::SyntheticScene(SyntheticScene&& o) noexcept : impl_(o.impl_) { o.impl_ = nullptr; }
SyntheticScene& SyntheticScene::operator=(SyntheticScene&& o) noexcept {
  std::swap(impl_, o.impl_);
  return *this;
}
std::size_t SyntheticScene::size() const { return static_cast<std::size_t>(impl_->opt.num_frames); }
const SynthOptions& SyntheticScene::options() const { return impl_->opt; }
double SyntheticScene::timestamp(std::size_t i) const {
  return impl_->opt.start_time + static_cast<double>(i) / impl_->opt.fps;
}
Eigen::Isometry3d SyntheticScene::camera_pose(double t) const { return impl_->camera_pose(t); }
SynthFrame SyntheticScene::render(std::size_t i) const {
  DS3D_CHECK(i < size(), "ds3d::synth::SyntheticScene::render: frame ", i, " out of range (size ",
             size(), ")");
  return impl_->render(i);
}

cv::Mat part_locations(const SynthFrame& frame, const PinholeCamera& camera) {
  DS3D_CHECK(frame.depth_true.type() == CV_32F && frame.human_id.type() == CV_8U &&
                 frame.depth_true.size() == frame.human_id.size(),
             "ds3d::synth::part_locations: frame lacks depth_true/human_id");
  cv::Mat out = cv::Mat::zeros(frame.depth_true.size(), CV_32FC3);
  for (int y = 0; y < out.rows; ++y) {
    for (int x = 0; x < out.cols; ++x) {
      const std::uint8_t h = frame.human_id.at<std::uint8_t>(y, x);
      const float z = frame.depth_true.at<float>(y, x);
      if (h == 0 || !(z > 0) || h > frame.boxes.size()) continue;
      const HumanBox& b = frame.boxes[h - 1U];
      const Eigen::Vector3d pw = frame.T_world_cam * camera.back_project(x, y, z);
      const Eigen::Vector3d local =
          Eigen::AngleAxisd(-b.yaw, Eigen::Vector3d::UnitZ()) * (pw - b.center);
      Eigen::Vector3d rel = (local.cwiseQuotient(b.size) + Eigen::Vector3d::Constant(0.5));
      rel = rel.cwiseMax(0.0).cwiseMin(1.0);
      out.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(rel.x()), static_cast<float>(rel.y()),
                                          static_cast<float>(rel.z()));
    }
  }
  return out;
}

namespace {

void write_png(const std::filesystem::path& p, const cv::Mat& img) {
  std::vector<std::uint8_t> buf;
  // Fast compression: the generator's time goes into rendering, not zlib.
  DS3D_CHECK_AS(IoError,
                cv::imencode(".png", img, buf,
                             {cv::IMWRITE_PNG_COMPRESSION, 1, cv::IMWRITE_PNG_STRATEGY,
                              cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY}),
                "ds3d::synth::generate_sequence: PNG encoding failed for '", p.string(), "'");
  detail::write_file_atomically(
      p, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()),
      "ds3d::synth::generate_sequence");
}

// CPU time of this thread: a shared, loaded machine inflates wall time, not CPU time.
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::string stamp_name(double t) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f", t);
  return buf;
}

std::string json_vec(const Eigen::Vector3d& v) {
  std::string out = "[";
  for (int k = 0; k < 3; ++k) {
    if (k > 0) out.push_back(',');
    out.append(detail::json_number(v[k]));
  }
  out.push_back(']');
  return out;
}

}  // namespace

SynthSummary generate_sequence(const std::filesystem::path& out_dir, const SynthOptions& options) {
  namespace fs = std::filesystem;
  const auto t_start = std::chrono::steady_clock::now();
  const SyntheticScene scene(options);
  std::error_code ec;
  for (const char* sub : {"rgb", "depth", "mask"}) fs::create_directories(out_dir / sub, ec);
  if (options.write_parts) {
    fs::create_directories(out_dir / "parts", ec);
    fs::create_directories(out_dir / "parts_loc", ec);
  }
  DS3D_CHECK_AS(IoError, fs::is_directory(out_dir / "mask", ec),
                "ds3d::synth::generate_sequence: cannot create '", out_dir.string(), "'");
  SynthSummary sum;
  std::string rgb_txt = "# color images (ds3d synthetic, scenario " +
                        scenario_name(options.scenario) + ", seed " + std::to_string(options.seed) +
                        ")\n# timestamp filename\n";
  std::string depth_txt = "# depth maps (16-bit PNG, " +
                          detail::json_number(options.camera.depth_scale) +
                          " units per metre, 0 = no depth)\n# timestamp filename\n";
  std::string boxes;
  double render_s = 0;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const double t0 = thread_cpu_seconds();
    const SynthFrame f = scene.render(i);
    render_s += thread_cpu_seconds() - t0;
    const std::string name = stamp_name(f.timestamp);
    const std::string dname = stamp_name(f.timestamp + 0.0005);  // depth stamps differ slightly
    write_png(out_dir / "rgb" / (name + ".png"), f.rgb);
    write_png(out_dir / "depth" / (dname + ".png"), f.depth);
    write_png(out_dir / "mask" / (name + ".png"), f.dynamic_mask);
    if (options.write_parts) {
      cv::Mat parts;
      const cv::Mat zero = cv::Mat::zeros(f.part_id.size(), CV_8U);
      cv::merge(std::vector<cv::Mat>{f.human_id, f.part_id, zero}, parts);
      write_png(out_dir / "parts" / (name + ".png"), parts);
      cv::Mat loc;
      part_locations(f, options.camera).convertTo(loc, CV_16UC3, 65535.0);
      write_png(out_dir / "parts_loc" / (name + ".png"), loc);
    }
    rgb_txt += name + " rgb/" + name + ".png\n";
    depth_txt += dname + " depth/" + dname + ".png\n";
    boxes += "{\"timestamp\":" + name + ",\"frame\":" + std::to_string(i) + ",\"boxes\":[";
    for (std::size_t k = 0; k < f.boxes.size(); ++k) {
      const HumanBox& b = f.boxes[k];
      if (k > 0) boxes += ",";
      boxes += "{\"id\":" + std::to_string(b.id) + ",\"center\":" + json_vec(b.center) +
               ",\"size\":" + json_vec(b.size) + ",\"yaw\":" + detail::json_number(b.yaw) +
               ",\"sitting\":" + (b.sitting ? "true" : "false") +
               ",\"visible_pixels\":" + std::to_string(b.visible_pixels) + "}";
      sum.dynamic_pixels += static_cast<std::size_t>(b.visible_pixels);
    }
    boxes += "]}\n";
    ++sum.frames;
  }
  // Ground truth at 100 Hz over the sequence (the camera path is analytic), like TUM's mocap.
  Trajectory gt;
  const double t_end = scene.timestamp(scene.size() - 1) + 0.05;
  for (int k = 0;; ++k) {
    const double t = options.start_time - 0.05 + k * 0.01;
    if (t > t_end) break;
    gt.push_back({t, scene.camera_pose(t)});
  }
  const auto& c = options.camera;
  std::string cam = "# ds3d synthetic pinhole camera\n";
  for (const auto& [k, v] :
       std::vector<std::pair<std::string, double>>{{"fx", c.fx},
                                                   {"fy", c.fy},
                                                   {"cx", c.cx},
                                                   {"cy", c.cy},
                                                   {"k1", 0},
                                                   {"k2", 0},
                                                   {"p1", 0},
                                                   {"p2", 0},
                                                   {"k3", 0},
                                                   {"depth_scale", c.depth_scale},
                                                   {"width", c.width},
                                                   {"height", c.height}}) {
    cam += k + " " + detail::json_number(v) + "\n";
  }
  constexpr const char* kFn = "ds3d::synth::generate_sequence";
  write_tum_trajectory(out_dir / "groundtruth.txt", gt);
  detail::write_file_atomically(out_dir / "camera.txt", cam, kFn);
  detail::write_file_atomically(out_dir / "boxes.jsonl", boxes, kFn);
  detail::write_file_atomically(out_dir / "depth.txt", depth_txt, kFn);
  detail::write_file_atomically(out_dir / "rgb.txt", rgb_txt, kFn);
  sum.render_seconds = render_s;
  sum.total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return sum;
}

}  // namespace ds3d::synth
