// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// libFuzzer target: a trajectory pair -> ATE -> plot (src/slam/trajectory_plot.cpp). The input
// is two TUM texts separated by the first NUL byte (ground truth, estimate). Only
// ds3d::IoError (parsing) and ds3d::InvalidArgument (too few pairs) may escape; the plot must
// be written. Run with `make fuzz`.
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "ds3d/slam/trajectory_plot.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  const std::size_t nul = all.find('\0');
  if (nul == std::string_view::npos) return 0;
  ds3d::Trajectory gt;
  ds3d::Trajectory est;
  try {
    gt = ds3d::parse_tum_trajectory(all.substr(0, nul), {.keep_zero_quaternion = true}).trajectory;
    est =
        ds3d::parse_tum_trajectory(all.substr(nul + 1), {.keep_zero_quaternion = true}).trajectory;
  } catch (const ds3d::IoError&) {
    return 0;
  }
  ds3d::AteResult r;
  try {
    r = ds3d::evaluate_ate(gt, est, {.max_difference = 0.5});
  } catch (const ds3d::InvalidArgument&) {
    return 0;
  }
  static const std::filesystem::path out =
      std::filesystem::temp_directory_path() /
      ("ds3d_ate_plot_fuzz_" + std::to_string(::getpid()) + ".png");
  ds3d::write_ate_plot(out, gt, r, {.width = 400, .height = 300, .title = "fuzz"});
  if (!std::filesystem::exists(out)) std::abort();
  return 0;
}
