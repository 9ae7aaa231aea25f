// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-slam --realtime: a recording played at its recorded rate, as a live camera delivers it.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <vector>

namespace ds3d_slam_tool {

/// Hands frames over no earlier than their recorded time: frame i is due (stamp_i − stamp_0)
/// seconds after the first frame was handed over. A frame the pipeline is not ready to take when
/// it is due is handed over late and counted, never dropped, so the trajectory is the same as
/// that of a run that reads as fast as it can. Used from one thread (the pipeline's reader).
class LivePacer {
 public:
  using Clock = std::chrono::steady_clock;

  /// Waits until the frame stamped `stamp` [s, the recording's clock] is due and returns its due
  /// time: when a live camera would have delivered it (the first frame: now). Records how late
  /// it is handed over (0 when on time; late when the pipeline was not ready or the thread woke
  /// late). Stops waiting early when `stop` returns true (checked every 20 ms).
  Clock::time_point wait(double stamp, const std::function<bool()>& stop);

  /// The lateness of every frame handed over so far [ms], in order.
  [[nodiscard]] const std::vector<double>& lag_ms() const { return lag_ms_; }

 private:
  std::optional<std::chrono::steady_clock::time_point> start_;
  double first_stamp_ = 0;
  std::vector<double> lag_ms_;
};

}  // namespace ds3d_slam_tool
