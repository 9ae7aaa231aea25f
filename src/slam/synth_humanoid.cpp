// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Humanoids: the walking and sitting motion, their capsule/ellipsoid meshes and their boxes.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "synth_impl.hpp"

namespace ds3d::synth {

Pose2 SyntheticScene::Impl::human_pose(const Human& h, double t) const {
  if (!h.route.empty()) return route_pose(h, t);
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

void SyntheticScene::Impl::human_meshes(std::size_t k, double t, std::vector<Mesh>& out) const {
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
      shoulder[side] = -0.25F - 0.35F * std::sin(0.9F * tt + 1.7F * static_cast<float>(side) + ph0);
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
  if (h.carried != 0) carried_mesh(k, p, out);
}

HumanBox SyntheticScene::Impl::box_of(std::size_t k, double t,
                                      const std::vector<Mesh>& meshes) const {
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
  b.carried = humans[k].carried;
  return b;
}

}  // namespace ds3d::synth
