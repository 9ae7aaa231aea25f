// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file build_info.hpp
/// @brief What the compiled part of ds3d (`ds3d::slam`) was built with. Needs target ds3d::slam.

#include <string>

#include "ds3d/detail/abi_guard.hpp"

namespace ds3d {

/// Versions and settings of the compiled library.
struct BuildInfo {
  std::string ds3d_version;    ///< "MAJOR.MINOR.PATCH"
  std::string opencv_version;  ///< OpenCV the library was compiled against
  std::string ceres_version;   ///< Ceres Solver the library was compiled against
  std::string eigen_version;   ///< Eigen "WORLD.MAJOR.MINOR"
  std::string compiler;        ///< compiler id and version
  bool debug = false;          ///< true when built without NDEBUG
  int hardware_threads = 0;    ///< std::thread::hardware_concurrency() on this machine
  /// SIMD level chosen at configure time (CMake option DS3D_SIMD): "avx2" (-mavx2 -mfma) or
  /// "none" (compiler baseline, SSE2 on x86-64).
  std::string simd;
  /// Instruction sets the library was actually compiled for, from the compiler's macros,
  /// e.g. "sse2 avx avx2 fma".
  std::string simd_isa;
  /// EIGEN_MAX_ALIGN_BYTES of the library (16 in every ds3d build; code sharing Eigen objects
  /// with the compiled libraries must use the same value: CMake target ds3d::abi sets it).
  int eigen_max_align_bytes = 0;
};

/// Returns the build information of the linked ds3d::slam library. Never throws.
[[nodiscard]] BuildInfo build_info();

/// One-line human-readable summary of build_info().
[[nodiscard]] std::string build_info_string();

}  // namespace ds3d
