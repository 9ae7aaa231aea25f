// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// libFuzzer target: camera.txt parsing. Only ds3d::IoError may escape; an accepted camera must
// validate. Run with `make fuzz`.
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "ds3d/slam/dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const ds3d::PinholeCamera c = ds3d::parse_camera_text(text, "fuzz");
    c.validate("fuzz");  // throws InvalidArgument (uncaught: a crash) if the parser let it through
  } catch (const ds3d::IoError&) {
  }
  return 0;
}
