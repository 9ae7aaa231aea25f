// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file version.hpp
/// @brief Library version. CMake reads the numbers below, so this file is the single source.

#define DS3D_VERSION_MAJOR 0
#define DS3D_VERSION_MINOR 1
#define DS3D_VERSION_PATCH 0

namespace ds3d {
/// Version string "MAJOR.MINOR.PATCH" of the headers in use.
inline constexpr const char* kVersion = "0.1.0";
}  // namespace ds3d
