// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// libFuzzer target: the TUM trajectory parser, then ATE/RPE of what it read against itself and a
// write/read round trip. Only ds3d::IoError / InvalidArgument may escape the parser; results
// must be finite. Run with `make fuzz`.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  for (const bool keep : {false, true}) {
    ds3d::TumReadResult r;
    try {
      r = ds3d::parse_tum_trajectory(text, {.keep_zero_quaternion = keep}, "fuzz");
    } catch (const ds3d::IoError&) {
      continue;
    }
    const auto& t = r.trajectory;
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (!t[i].T_world_cam.matrix().allFinite()) std::abort();
      if (i > 0 && !(t[i - 1].timestamp < t[i].timestamp)) std::abort();
    }
    try {
      const auto a = ds3d::evaluate_ate(t, t);
      if (!std::isfinite(a.rmse) || a.compared_pose_pairs != t.size()) std::abort();
    } catch (const ds3d::InvalidArgument&) {
    }
    try {
      const auto p = ds3d::evaluate_rpe(t, t, {.delta = 1, .delta_unit = ds3d::DeltaUnit::kFrames});
      if (!std::isfinite(p.translational.rmse) || !std::isfinite(p.rotational.rmse)) std::abort();
    } catch (const ds3d::InvalidArgument&) {
    }
    try {
      const auto back = ds3d::parse_tum_trajectory(ds3d::format_tum_trajectory(t));
      if (back.trajectory.size() != t.size()) std::abort();
      for (std::size_t i = 0; i < t.size(); ++i) {
        if (back.trajectory[i].timestamp != t[i].timestamp) std::abort();
      }
    } catch (const ds3d::InvalidArgument&) {
      // timestamps whose round trip is not finite cannot be written: fine
    }
  }
  return 0;
}
