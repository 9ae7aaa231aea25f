// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file version.hpp
/// @brief Library version. CMake reads the numbers below, so this file is the single source.

/// Major version: incompatible API changes.
#define DS3D_VERSION_MAJOR 0
/// Minor version: compatible additions (the package accepts the same minor version).
#define DS3D_VERSION_MINOR 1
/// Patch version: fixes only.
#define DS3D_VERSION_PATCH 0

namespace ds3d {
/// Version string "MAJOR.MINOR.PATCH" of the headers in use.
inline constexpr const char* kVersion = "0.1.0";
}  // namespace ds3d
