// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d_slam/live_pacer.hpp"

#include <algorithm>
#include <thread>

namespace ds3d_slam_tool {

LivePacer::Clock::time_point LivePacer::wait(double stamp, const std::function<bool()>& stop) {
  const auto now = Clock::now();
  if (!start_) {
    start_ = now;
    first_stamp_ = stamp;
    lag_ms_.push_back(0.0);
    return now;
  }
  // Clamped to ±10⁶ s (11 days), so that no stamp difference overflows the clock's ticks.
  const double offset_s = std::clamp(stamp - first_stamp_, -1e6, 1e6);
  const auto due = *start_ + std::chrono::duration_cast<Clock::duration>(
                                 std::chrono::duration<double>(offset_s));
  // In slices, so that a stop request during a long gap in the recording is seen.
  constexpr auto kSlice = std::chrono::milliseconds(20);
  auto t = now;
  while (t < due && !(stop && stop())) {
    std::this_thread::sleep_until(std::min(due, t + kSlice));
    t = Clock::now();
  }
  lag_ms_.push_back(std::max(0.0, std::chrono::duration<double, std::milli>(t - due).count()));
  return due;
}

}  // namespace ds3d_slam_tool
