// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Readers for the preprocessing golden fixtures (tests/data/preprocess/, a trimmed copy of
// ../shared/fixtures/preprocess; see its README.md) and the list of fixture roots to test.

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "ds3d/cloud.hpp"
#include "support/files.hpp"

namespace ds3d::test {

/// Fixture roots: the in-repo trimmed copy, plus the full set when available
/// ($DS3D_PREPROCESS_FIXTURES, else ../shared/fixtures/preprocess beside the source tree).
inline std::vector<std::filesystem::path> preprocess_fixture_roots() {
  std::vector<std::filesystem::path> roots{data_path("preprocess")};
  std::filesystem::path full;
  if (const char* env = std::getenv("DS3D_PREPROCESS_FIXTURES"); env != nullptr && *env != '\0') {
    full = env;
  } else {
    full = std::filesystem::path(DS3D_SOURCE_DIR) / ".." / "shared" / "fixtures" / "preprocess";
  }
  if (std::filesystem::exists(full / "cube_1k" / "case.json")) roots.push_back(full);
  return roots;
}

/// The point-cloud cases (every directory with an input.bin), sorted by name.
inline std::vector<std::filesystem::path> preprocess_cases(const std::filesystem::path& root) {
  std::vector<std::filesystem::path> out;
  for (const auto& e : std::filesystem::directory_iterator(root)) {
    if (e.is_directory() && std::filesystem::exists(e.path() / "input.bin"))
      out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// Little-endian float32 N×3 file.
inline Points3f read_points_bin(const std::filesystem::path& p) {
  const std::string bytes = read_file(p);
  DS3D_CHECK_AS(IoError, bytes.size() % 12 == 0, "test: ", p.string(), " size is not N*12");
  Points3f pts(static_cast<Eigen::Index>(bytes.size() / 12), 3);
  if (!bytes.empty()) std::memcpy(pts.data(), bytes.data(), bytes.size());
  return pts;
}

/// One row of a golden voxel file.
struct GoldenVoxel {
  std::array<std::int64_t, 3> key;
  std::uint32_t count;
  std::array<double, 3> centroid;
};

/// Golden voxel CSV (header ix,iy,iz,count,cx,cy,cz; sorted by key).
inline std::vector<GoldenVoxel> read_voxel_csv(const std::filesystem::path& p) {
  const auto lines = read_lines(p);
  std::vector<GoldenVoxel> out;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    GoldenVoxel v{};
    std::istringstream ss(lines[i]);
    char comma = 0;
    ss >> v.key[0] >> comma >> v.key[1] >> comma >> v.key[2] >> comma >> v.count >> comma >>
        v.centroid[0] >> comma >> v.centroid[1] >> comma >> v.centroid[2];
    DS3D_CHECK_AS(IoError, !ss.fail(), "test: bad line in ", p.string(), ": ", lines[i]);
    out.push_back(v);
  }
  return out;
}

/// One index per line.
inline std::vector<std::uint32_t> read_indices(const std::filesystem::path& p) {
  std::vector<std::uint32_t> out;
  for (const auto& l : read_lines(p)) out.push_back(static_cast<std::uint32_t>(std::stoul(l)));
  return out;
}

}  // namespace ds3d::test
