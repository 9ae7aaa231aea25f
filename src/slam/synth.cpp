// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Scenario names, option checks and the SyntheticScene handle over its implementation.
#include "ds3d/slam/synth.hpp"

#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "ds3d/errors.hpp"
#include "synth_impl.hpp"

namespace ds3d::synth {

Scenario parse_scenario(std::string_view name) {
  static const std::pair<std::string_view, Scenario> kNames[] = {
      {"static_room", Scenario::kStaticRoom},
      {"walking_static", Scenario::kWalkingStatic},
      {"walking_xyz", Scenario::kWalkingXyz},
      {"walking_halfsphere", Scenario::kWalkingHalfsphere},
      {"walking_rpy", Scenario::kWalkingRpy},
      {"sitting_static", Scenario::kSittingStatic},
      {"sitting_xyz", Scenario::kSittingXyz},
      {"crowd_cross", Scenario::kCrowdCross},
      {"crowd_board", Scenario::kCrowdBoard},
      {"crowd_start", Scenario::kCrowdStart},
      {"crowd_handheld", Scenario::kCrowdHandheld}};
  for (const auto& [n, s] : kNames) {
    if (n == name) return s;
  }
  throw InvalidArgument(detail::concat(
      "ds3d::synth::parse_scenario: unknown scenario '", name,
      "' (valid: static_room, walking_static, walking_xyz, walking_halfsphere, walking_rpy, "
      "sitting_static, sitting_xyz, crowd_cross, crowd_board, crowd_start, crowd_handheld)"));
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
    case Scenario::kCrowdCross:
      return "crowd_cross";
    case Scenario::kCrowdBoard:
      return "crowd_board";
    case Scenario::kCrowdStart:
      return "crowd_start";
    case Scenario::kCrowdHandheld:
      return "crowd_handheld";
  }
  return "unknown";
}

void SynthOptions::validate() const {
  constexpr const char* kFn = "ds3d::synth::SynthOptions";
  DS3D_CHECK(num_frames >= 1 && num_frames <= 100000, kFn,
             ": num_frames must be in [1, 100000] (got ", num_frames, ")");
  if (is_crowd(scenario)) {
    DS3D_CHECK(num_humans == -1 || (num_humans >= 3 && num_humans <= 6), kFn,
               ": num_humans must be in [3, 6] or -1 for crowd scenarios (got ", num_humans, ")");
  } else {
    DS3D_CHECK(num_humans >= -1 && num_humans <= 4, kFn,
               ": num_humans must be in [0, 4] or -1 (got ", num_humans, ")");
  }
  DS3D_CHECK(std::isfinite(detection_miss) && detection_miss >= 0 && detection_miss <= 0.8, kFn,
             ": detection_miss must be in [0, 0.8] (got ", detection_miss, ")");
  DS3D_CHECK(std::isfinite(detection_false) && detection_false >= 0 && detection_false <= 1, kFn,
             ": detection_false must be in [0, 1] (got ", detection_false, ")");
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

}  // namespace ds3d::synth
