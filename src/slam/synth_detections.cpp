// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Detector errors for detections_noisy.jsonl: person boxes missed in runs, false boxes on walls.
#include "synth_detections.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "ds3d/detail/json.hpp"

namespace ds3d::synth {

namespace {

constexpr double kMeanMissRun = 5.0;  // frames a missed person stays missed, on average
constexpr double kTrueScore = 0.9;
constexpr double kFalseScore = 0.6;

std::string corners_json(const Eigen::Vector3d& center, const Eigen::Vector3d& size, double yaw,
                         const Eigen::Isometry3d& T_cam_world) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  std::string out = "[";
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d local(((c & 1) != 0 ? 0.5 : -0.5) * size.x(),
                                ((c & 2) != 0 ? 0.5 : -0.5) * size.y(),
                                ((c & 4) != 0 ? 0.5 : -0.5) * size.z());
    const Eigen::Vector3d p = T_cam_world * (center + r * local);
    if (c > 0) out += ",";
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on chained operator+ here.
    out += '[';
    out += detail::json_number(p.x());
    out += ',';
    out += detail::json_number(p.y());
    out += ',';
    out += detail::json_number(p.z());
    out += ']';
  }
  out += ']';
  return out;
}

std::string box_json(const std::string& corners, double score) {
  std::string out = "{\"corners\":";
  out += corners;
  out += ",\"score\":";
  out += detail::json_number(score);
  out += ",\"class\":\"person\"}";
  return out;
}

}  // namespace

NoisyDetections::NoisyDetections(const SynthOptions& opt)
    : miss_(opt.detection_miss),
      false_(opt.detection_false),
      camera_(opt.camera),
      rng_(mix(opt.seed ^ 0xde7e'c7ed'0000'0002ULL)) {}

int NoisyDetections::min_visible_pixels(const PinholeCamera& camera) {
  return std::max(20, camera.width * camera.height / 500);
}

void NoisyDetections::add(const SynthFrame& f, const std::string& stamp) {
  std::uniform_real_distribution<double> u01(0, 1);
  // Two-state chain per person: stationary miss probability miss_, mean run kMeanMissRun.
  const double p_recover = 1.0 / kMeanMissRun;
  const double p_miss = std::min(1.0, miss_ / (1.0 - miss_) * p_recover);
  const Eigen::Isometry3d T_cw = f.T_world_cam.inverse();
  std::string line = "{\"timestamp\":" + stamp + ",\"boxes\":[";
  bool first = true;
  for (const HumanBox& b : f.boxes) {
    const auto k = static_cast<std::size_t>(b.id);
    if (missed_.size() <= k) {
      missed_.resize(k + 1, false);
      missed_[k] = u01(rng_) < miss_;
    } else {
      missed_[k] = missed_[k] ? u01(rng_) >= p_recover : u01(rng_) < p_miss;
    }
    if (missed_[k] || b.visible_pixels < min_visible_pixels(camera_)) continue;
    if (!first) line += ",";
    first = false;
    line += box_json(corners_json(b.center, b.size, b.yaw, T_cw), kTrueScore);
  }
  if (u01(rng_) < false_) {
    // A person-sized box centred on a static surface point seen in this frame.
    std::uniform_int_distribution<int> px(0, camera_.width - 1);
    std::uniform_int_distribution<int> py(0, camera_.height - 1);
    for (int tries = 0; tries < 200; ++tries) {
      const int x = px(rng_);
      const int y = py(rng_);
      const float z = f.depth_true.at<float>(y, x);
      if (f.human_id.at<std::uint8_t>(y, x) != 0 || !(z > 0.3F)) continue;
      const Eigen::Vector3d pw = f.T_world_cam * camera_.back_project(x, y, z);
      const Eigen::Vector3d size(0.55, 0.6, 1.0 + 0.7 * u01(rng_));
      const double yaw = (2 * u01(rng_) - 1) * kPi;
      if (!first) line += ",";
      line += box_json(corners_json(pw, size, yaw, T_cw), kFalseScore);
      break;
    }
  }
  text_ += line + "]}\n";
}

}  // namespace ds3d::synth
