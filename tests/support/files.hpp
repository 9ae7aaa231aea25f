// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Helpers for reading test fixtures (tests/data/...) and locating optional real data.

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "ds3d/detail/json.hpp"
#include "ds3d/errors.hpp"

namespace ds3d::test {

/// tests/data/<relative>.
inline std::filesystem::path data_path(const std::string& relative) {
  return std::filesystem::path(DS3D_TEST_DATA_DIR) / relative;
}

/// Whole file as bytes; throws IoError when it cannot be read.
inline std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  DS3D_CHECK_AS(IoError, in.good(), "test: cannot open ", p.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline detail::JsonValue read_json(const std::filesystem::path& p) {
  return detail::parse_json(read_file(p));
}

/// Non-empty lines of a text file.
inline std::vector<std::string> read_lines(const std::filesystem::path& p) {
  std::istringstream in(read_file(p));
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) {
    if (!l.empty() && l.back() == '\r') l.pop_back();
    if (!l.empty()) lines.push_back(l);
  }
  return lines;
}

/// Root of the optional real recorded data: $DS3D_DATA_DIR, else ../shared/data beside the
/// source tree. Returns an empty path when it does not exist (tests then GTEST_SKIP).
inline std::filesystem::path shared_data_dir() {
  if (const char* env = std::getenv("DS3D_DATA_DIR"); env != nullptr && *env != '\0') {
    return std::filesystem::exists(env) ? std::filesystem::path(env) : std::filesystem::path();
  }
  const auto p = std::filesystem::path(DS3D_SOURCE_DIR) / ".." / "shared" / "data";
  return std::filesystem::exists(p) ? p : std::filesystem::path();
}

}  // namespace ds3d::test
