// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Linking ds3d::ds3d (core + the compiled slam library) from an installed package.
#include <cstdio>

#include <ds3d/slam/build_info.hpp>
#include <ds3d/ds3d.hpp>

int main() {
  std::printf("%s\n", ds3d::build_info_string().c_str());
  return ds3d::build_info().ds3d_version == ds3d::kVersion ? 0 : 1;
}
