// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The procedural scene: textures, room, furniture, clutter, humans' paths and the camera path.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "synth_impl.hpp"

namespace ds3d::synth {

namespace {

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

}  // namespace

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

Eigen::Isometry3d SyntheticScene::Impl::camera_pose(double t_abs) const {
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
      motion.linear() =
          Eigen::AngleAxisd(0.004 * std::sin(0.9 * t), Eigen::Vector3d::UnitY()).toRotationMatrix();
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
    case Scenario::kCrowdCross:
    case Scenario::kCrowdBoard:
    case Scenario::kCrowdStart:
    case Scenario::kCrowdHandheld:
      motion = crowd_motion(t);
      break;
    case Scenario::kWalkingHalfsphere: {
      // Camera on a sphere of radius 1 m around a point 1 m ahead, looking at it.
      const double az = 0.6 * std::sin(w * t / 12.0);
      const double el = 0.25 + 0.2 * std::sin(w * t / 9.0);
      const Eigen::Vector3d centre(1.5, opt.room_size.y() / 2, 1.2);
      const Eigen::Vector3d eye =
          centre +
          Eigen::Vector3d(-std::cos(el) * std::cos(az), -std::cos(el) * std::sin(az), std::sin(el));
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

void SyntheticScene::Impl::build(std::mt19937_64& rng) {
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

  if (crowd()) {  // people, routes and shake from a stream of their own
    build_crowd();
    if (opt.extra_furniture > 0) add_clutter(room_x, room_y);
    return;
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

double SyntheticScene::Impl::distance_to_humans(const Eigen::Vector2d& p) const {
  double best = std::numeric_limits<double>::infinity();
  for (const Human& h : humans) {
    for (std::size_t i = 0; i < h.route.size(); ++i) {
      const Eigen::Vector2d a = h.route[i].xy;
      const Eigen::Vector2d ab = h.route[(i + 1) % h.route.size()].xy - a;
      const double s = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
      best = std::min(best, (p - (a + s * ab)).norm());
    }
    if (!h.route.empty()) continue;
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

void SyntheticScene::Impl::add_clutter(double room_x, double room_y) {
  std::mt19937_64 rng(mix(opt.seed ^ 0x5eed'c1a7'7e12'0001ULL));
  std::uniform_real_distribution<double> u01(0, 1);
  const auto uni = [&](double a, double b) { return a + (b - a) * u01(rng); };
  const auto box = [](Mesh& m, double x0, double y0, double z0, double x1, double y1, double z1) {
    add_box(m,
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

}  // namespace ds3d::synth
