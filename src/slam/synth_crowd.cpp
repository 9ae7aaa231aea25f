// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Crowd stress scenarios: people on routes close to a handheld camera, carried objects, blur.
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

using Waypoint = Human::Waypoint;

constexpr double kCamX = 0.5;        // camera start, 0.5 m from the x = 0 wall
constexpr double kShakeDt = 0.1;     // shake knot spacing [s]
constexpr double kShakeT0 = -1.0;    // first knot (the ground truth starts before frame 0)
constexpr double kExposure = 0.5;    // exposure as a fraction of the frame interval
constexpr double kMinBlurPx = 1.5;   // shorter blur is left out (sharp frame)
constexpr double kHalfWidth = 0.28;  // a person's half width for the view layout [m]

double wrap_angle(double a) { return std::atan2(std::sin(a), std::cos(a)); }

// What each person does; the first ones are the close crossers or standers.
enum class Role : std::uint8_t { kEdgeCrosser, kStopCrosser, kCloseStander, kFarStander, kWander };

struct Layout {
  std::array<Role, 6> roles;
  std::array<int, 6> carried;  // per person: 0 nothing, 1 board, 2 box, 3 bag
  int default_humans;
};

Layout layout_of(Scenario s) {
  using R = Role;
  switch (s) {
    case Scenario::kCrowdBoard:
      return {{R::kEdgeCrosser, R::kStopCrosser, R::kWander, R::kWander, R::kWander, R::kWander},
              {1, 2, 3, 0, 2, 0},
              3};
    case Scenario::kCrowdStart:
      return {{R::kCloseStander, R::kFarStander, R::kWander, R::kWander, R::kWander, R::kWander},
              {0, 3, 0, 2, 0, 0},
              5};
    case Scenario::kCrowdHandheld:
      return {{R::kEdgeCrosser, R::kStopCrosser, R::kWander, R::kWander, R::kWander, R::kWander},
              {0, 3, 0, 0, 2, 0},
              4};
    default:  // crowd_cross
      return {{R::kEdgeCrosser, R::kStopCrosser, R::kWander, R::kWander, R::kWander, R::kWander},
              {0, 0, 0, 2, 0, 0},
              4};
  }
}

// Catmull-Rom interpolation of the shake knots at time t.
Eigen::Matrix<double, 6, 1> shake_at(const std::vector<Eigen::Matrix<double, 6, 1>>& knots,
                                     double t) {
  const double u = std::max(0.0, (t - kShakeT0) / kShakeDt);
  const auto last = static_cast<std::ptrdiff_t>(knots.size()) - 1;
  const auto i = std::min(static_cast<std::ptrdiff_t>(u), last);
  const double f = std::min(u - static_cast<double>(i), 1.0);
  const auto at = [&](std::ptrdiff_t j) { return knots[std::clamp<std::ptrdiff_t>(j, 0, last)]; };
  const auto p0 = at(i - 1), p1 = at(i), p2 = at(i + 1), p3 = at(i + 2);
  return 0.5 * ((2 * p1) + (-p0 + p2) * f + (2 * p0 - 5 * p1 + 4 * p2 - p3) * f * f +
                (-p0 + 3 * p1 - 3 * p2 + p3) * f * f * f);
}

}  // namespace

void SyntheticScene::Impl::build_crowd() {
  std::mt19937_64 rng(mix(opt.seed ^ 0xc20d'5eed'0000'0001ULL));
  std::uniform_real_distribution<double> u01(0, 1);
  const auto uni = [&](double a, double b) { return a + (b - a) * u01(rng); };
  const double room_x = opt.room_size.x();
  const double cy = opt.room_size.y() / 2;
  const double y_out = cy - 0.9;  // lateral reach of a crossing: out of view, clear of the walls
  const Layout lay = layout_of(opt.scenario);
  const int n = opt.num_humans < 0 ? lay.default_humans : opt.num_humans;
  // Angular intervals (seen from the camera start) of the people placed so far at t = 0, so that
  // the wanderers start where they are not hidden behind the close people.
  std::vector<std::pair<double, double>> taken;
  const auto interval = [&](const Eigen::Vector2d& p) {
    const double d = p.x() - kCamX;
    return std::make_pair(std::atan2(p.y() - cy, d), std::atan2(kHalfWidth, d));
  };
  for (int k = 0; k < n; ++k) {
    Human h;
    h.height = uni(1.55, 1.95);
    h.width = uni(0.85, 1.2);
    h.speed = uni(0.8, 1.3);
    h.mat_shirt = static_cast<int>(textures.size());
    textures.push_back(make_cloth(rng));
    h.mat_pants = static_cast<int>(textures.size());
    textures.push_back(make_cloth(rng));
    h.mat_skin = static_cast<int>(textures.size());
    textures.push_back(
        make_texture(rng, cv::Scalar(uni(60, 150), uni(90, 170), uni(140, 220)), 12, 4, 12));
    h.carried = lay.carried[static_cast<std::size_t>(k)];
    h.mat_carried = static_cast<int>(textures.size());
    textures.push_back(make_texture(rng, cv::Scalar(uni(80, 220), uni(80, 220), uni(80, 220)),
                                    h.carried == 1 ? 30 : 60, 6, 40));
    const double side = u01(rng) < 0.5 ? -1.0 : 1.0;
    const auto at = [&](double d, double dy) { return Eigen::Vector2d(kCamX + d, cy + dy); };
    switch (lay.roles[static_cast<std::size_t>(k)]) {
      case Role::kEdgeCrosser: {  // starts cut by an image edge, crosses 0.6-0.9 m ahead
        const double d = uni(0.6, 0.9);
        h.route = {{at(d, side * 0.65 * d), 0.0},
                   {at(d, -side * y_out), uni(0.6, 1.2)},
                   {at(d + 0.4, side * y_out), uni(0.6, 1.2)}};
        break;
      }
      case Role::kStopCrosser: {  // from the other edge, stops in front, turns, walks on
        const double d = uni(0.7, 1.0);
        h.route = {{at(d, -side * 0.6 * d), 0.0},
                   {at(d, uni(-0.1, 0.1)), uni(1.0, 2.0)},
                   {at(d, side * y_out), 0.8},
                   {at(d + 0.3, -side * y_out), 0.8}};
        h.route[1].face = kPi;
        break;
      }
      case Role::kCloseStander: {  // stands close, facing the camera, then walks away
        const double d = uni(0.9, 1.1);
        h.route = {{at(d, side * uni(0.3, 0.4)), uni(1.5, 2.5)},
                   {at(d + 1.5, side * 1.2), 1.0},
                   {at(d + 0.3, side * y_out), 0.5}};
        h.route[0].face = kPi;
        break;
      }
      case Role::kFarStander: {  // stands 1.8-2.2 m ahead on the other side, then wanders
        const double d = uni(1.8, 2.2);
        h.route = {{at(d, -side * uni(0.45, 0.6)), uni(1.0, 2.0)},
                   {at(d + 0.8, -side * 1.0), 0.7},
                   {at(d - 0.6, -side * y_out), 0.5}};
        h.route[0].face = kPi;
        break;
      }
      case Role::kWander: {  // random stops 2-3.5 m ahead, starting in a free part of the view
        const double dmax = std::min(3.5, room_x - 1.2 - kCamX);
        Eigen::Vector2d p0 = Eigen::Vector2d::Zero();  // set by the first candidate
        double best = -std::numeric_limits<double>::infinity();
        for (int tries = 0; tries < 60; ++tries) {  // the start with the widest angular gap
          const double d = uni(2.0, dmax);
          const Eigen::Vector2d p = at(d, uni(-0.45, 0.45) * d);
          const auto [a, w] = interval(p);
          double gap = std::numeric_limits<double>::infinity();
          for (const auto& [b, v] : taken) gap = std::min(gap, std::abs(a - b) - w - v);
          if (gap > best) {
            best = gap;
            p0 = p;
          }
        }
        h.route = {{p0, uni(0.0, 1.5)}};
        for (int w = 0; w < 3; ++w) {
          const double d = uni(2.0, dmax);
          h.route.push_back({at(d, uni(-0.5, 0.5) * d), uni(0.0, 1.5)});
        }
        break;
      }
    }
    taken.push_back(interval(h.route[0].xy));
    h.a = h.route[0].xy;
    h.b = h.route[1].xy;
    humans.push_back(std::move(h));
  }
  // Shake: mean-reverting random walk of rotation [rad] and translation [m], 10 Hz knots.
  const bool fast = opt.scenario == Scenario::kCrowdHandheld;
  const double s_rot = fast ? 0.004 : 0.002;
  const double s_trans = fast ? 0.004 : 0.002;
  std::normal_distribution<double> g01(0, 1);
  const auto knots = static_cast<std::size_t>(
      (static_cast<double>(opt.num_frames) / opt.fps + 2 - kShakeT0) / kShakeDt + 4);
  Eigen::Matrix<double, 6, 1> s = Eigen::Matrix<double, 6, 1>::Zero();
  for (std::size_t i = 0; i < knots; ++i) {
    for (int j = 0; j < 6; ++j) s[j] = 0.85 * s[j] + (j < 3 ? s_rot : s_trans) * g01(rng);
    shake.push_back(s);
  }
  // Smooth path: random signs and periods, zero at t = 0 so that the layout above is in view.
  path.resize(12);
  for (int j = 0; j < 6; ++j) {
    path[2 * j] = u01(rng) < 0.5 ? -1.0 : 1.0;
    path[2 * j + 1] = uni(0.85, 1.15);
  }
}

Eigen::Isometry3d SyntheticScene::Impl::crowd_motion(double t) const {
  const bool fast = opt.scenario == Scenario::kCrowdHandheld;
  const double w = 2 * kPi;
  // Amplitudes [rad, m] and periods [s]: yaw, pitch, roll, x (right), y (down), z (forward).
  static constexpr std::array<double, 6> kAmp = {0.18, 0.06, 0.03, 0.20, 0.05, 0.20};
  static constexpr std::array<double, 6> kAmpFast = {0.35, 0.12, 0.05, 0.30, 0.10, 0.25};
  static constexpr std::array<double, 6> kPer = {8, 7, 5, 9, 6, 11};
  static constexpr std::array<double, 6> kPerFast = {4, 3.5, 5, 6, 5, 8};
  std::array<double, 6> v{};
  for (std::size_t j = 0; j < 6; ++j) {
    const double amp = (fast ? kAmpFast : kAmp)[j] * path[2 * j];
    const double per = (fast ? kPerFast : kPer)[j] * path[2 * j + 1];
    v[j] = amp * std::sin(w * t / per);
  }
  const Eigen::Matrix<double, 6, 1> s = shake_at(shake, t);
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d rv = s.head<3>();
  m.linear() = (Eigen::AngleAxisd(v[0], Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(v[1], Eigen::Vector3d::UnitX()) *
                Eigen::AngleAxisd(v[2], Eigen::Vector3d::UnitZ()))
                   .toRotationMatrix() *
               (rv.norm() > 0 ? Eigen::AngleAxisd(rv.norm(), rv.normalized()).toRotationMatrix()
                              : Eigen::Matrix3d::Identity());
  m.translation() = Eigen::Vector3d(v[3], v[4], v[5]) + s.tail<3>();
  return m;
}

Pose2 SyntheticScene::Impl::route_pose(const Human& h, double t) const {
  const auto& r = h.route;
  const std::size_t n = r.size();
  const auto leg = [&](std::size_t i) { return r[(i + 1) % n].xy - r[i].xy; };
  double period = 0;
  double loop_len = 0;
  for (std::size_t i = 0; i < n; ++i) {
    period += r[i].dwell + leg(i).norm() / h.speed;
    loop_len += leg(i).norm();
  }
  const double loops = std::floor(t / period);
  double tau = t - loops * period;
  double dist = loops * loop_len;  // walked so far: drives the gait phase
  const double stride = 0.75 * h.height;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d out = leg(i);
    const Eigen::Vector2d in = leg((i + n - 1) % n);
    const double yaw_out = std::atan2(out.y(), out.x());
    if (tau < r[i].dwell) {  // standing: turn from the incoming heading to the next leg
      const double yaw_in = std::isfinite(r[i].face) ? r[i].face : std::atan2(in.y(), in.x());
      const double f = std::isfinite(r[i].face) ? std::max(0.0, (tau / r[i].dwell - 0.7) / 0.3)
                                                : tau / r[i].dwell;
      return {r[i].xy, yaw_in + f * wrap_angle(yaw_out - yaw_in), 2 * kPi * dist / stride};
    }
    tau -= r[i].dwell;
    const double len = out.norm();
    if (tau < len / h.speed || i + 1 == n) {
      const double along = std::min(tau * h.speed, len);
      return {r[i].xy + out * (along / len), yaw_out, 2 * kPi * (dist + along) / stride};
    }
    tau -= len / h.speed;
    dist += len;
  }
  return {r[0].xy, 0.0, 0.0};
}

void SyntheticScene::Impl::carried_mesh(std::size_t k, const Pose2& p,
                                        std::vector<Mesh>& out) const {
  const Human& h = humans[k];
  const auto s = static_cast<float>(h.height / 1.75);
  const auto g = static_cast<float>(h.width);
  Mesh m;
  m.material = h.mat_carried;
  m.human = static_cast<std::uint8_t>(k + 1);
  m.part = 0;  // not a body part
  // Local frame as the body: x forward, y left, z up, origin on the floor under the hips.
  if (h.carried == 1) {  // a 1 x 0.7 m board held upright at the right side, under the arm
    const float y0 = -0.30F * s * g - 0.08F;
    add_box(m, {-0.5F, y0 - 0.02F, 0.40F * s}, {0.5F, y0, 0.40F * s + 0.7F}, 150.0F);
  } else if (h.carried == 2) {  // a box held in front of the chest
    add_box(m, {0.16F * s * g, -0.20F, 0.85F * s}, {0.16F * s * g + 0.35F, 0.20F, 0.85F * s + 0.3F},
            150.0F);
  } else {  // a bag hanging at the left side
    const float y0 = 0.28F * s * g;
    add_box(m, {-0.13F, y0, 0.42F * s}, {0.13F, y0 + 0.12F, 0.42F * s + 0.36F}, 150.0F);
  }
  const Eigen::Matrix3f rot =
      Eigen::AngleAxisf(static_cast<float>(p.yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix();
  const Eigen::Vector3f t(static_cast<float>(p.xy.x()), static_cast<float>(p.xy.y()), 0);
  for (auto& v : m.pos) v = rot * v + t;
  out.push_back(std::move(m));
}

void SyntheticScene::Impl::motion_blur(SynthFrame& f) const {
  const auto& cam = opt.camera;
  // Mean image motion of static points over one frame interval, from the true depth.
  const Eigen::Isometry3d prev_cw = camera_pose(f.timestamp - 1.0 / opt.fps).inverse();
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  int count = 0;
  for (int gy = 1; gy < 8; ++gy) {
    for (int gx = 1; gx < 10; ++gx) {
      const int x = gx * cam.width / 10;
      const int y = gy * cam.height / 8;
      const float z = f.depth_true.at<float>(y, x);
      if (!(z > 0)) continue;
      const Eigen::Vector3d pc = prev_cw * (f.T_world_cam * cam.back_project(x, y, z));
      if (!(pc.z() > 0.05)) continue;
      const Eigen::Vector2d q(cam.fx * pc.x() / pc.z() + cam.cx, cam.fy * pc.y() / pc.z() + cam.cy);
      sum += Eigen::Vector2d(x, y) - q;
      ++count;
    }
  }
  if (count == 0) return;
  const Eigen::Vector2d d = sum / count;
  const double len = kExposure * d.norm();
  if (len < kMinBlurPx) return;
  f.blur_px = len;
  const int size = 2 * static_cast<int>(std::ceil(len / 2)) + 1;
  cv::Mat kernel = cv::Mat::zeros(size, size, CV_32F);
  const Eigen::Vector2d u = d.normalized() * (len / 2);
  const double c = (size - 1) / 2.0;
  // Sub-pixel line by dense sampling, so that the kernel length follows len smoothly.
  const int samples = 8 * size;
  for (int i = 0; i <= samples; ++i) {
    const double a = -1.0 + 2.0 * i / samples;
    const double px = c + a * u.x();
    const double py = c + a * u.y();
    const int x0 = static_cast<int>(std::floor(px));
    const int y0 = static_cast<int>(std::floor(py));
    const double fx = px - x0;
    const double fy = py - y0;
    const auto add = [&](int x, int y, double wgt) {
      if (x >= 0 && y >= 0 && x < size && y < size)
        kernel.at<float>(y, x) += static_cast<float>(wgt);
    };
    add(x0, y0, (1 - fx) * (1 - fy));
    add(x0 + 1, y0, fx * (1 - fy));
    add(x0, y0 + 1, (1 - fx) * fy);
    add(x0 + 1, y0 + 1, fx * fy);
  }
  kernel /= cv::sum(kernel)[0];
  cv::filter2D(f.rgb, f.rgb, -1, kernel, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);
}

}  // namespace ds3d::synth
