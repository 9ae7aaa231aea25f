// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// libFuzzer target: rgb.txt/depth.txt list parsing and the associate.py association of a list
// with itself shifted. Only ds3d::IoError may escape. Run with `make fuzz`.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string_view>
#include <vector>

#include "ds3d/detail/tum_text.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const auto list = ds3d::detail::parse_tum_list(text, "fuzz", "fuzz");
    std::vector<double> stamps;
    for (const auto& e : list) {
      if (!std::isfinite(e.timestamp) || e.values.empty()) std::abort();
      if (!stamps.empty() && !(stamps.back() < e.timestamp)) std::abort();
      stamps.push_back(e.timestamp);
    }
    const auto m = ds3d::associate_timestamps(stamps, stamps, 0.0, 0.02);
    if (m.size() != stamps.size()) std::abort();  // every stamp matches itself at distance 0
    (void)ds3d::associate_timestamps(stamps, stamps, 0.013, 0.02);
  } catch (const ds3d::IoError&) {
  }
  return 0;
}
