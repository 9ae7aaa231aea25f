// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/build_info.hpp"

#include <thread>

#include <Eigen/Core>
#include <opencv2/core/version.hpp>

#include "ds3d/version.hpp"

#define DS3D_STR2(x) #x
#define DS3D_STR(x) DS3D_STR2(x)

namespace ds3d {

BuildInfo build_info() {
  BuildInfo info;
  info.ds3d_version = kVersion;
  info.opencv_version = CV_VERSION;
#ifdef DS3D_CERES_VERSION
  info.ceres_version = DS3D_CERES_VERSION;
#endif
  info.eigen_version = DS3D_STR(EIGEN_WORLD_VERSION) "." DS3D_STR(EIGEN_MAJOR_VERSION) "." DS3D_STR(
      EIGEN_MINOR_VERSION);
#if defined(__clang__)
  info.compiler = "clang " __clang_version__;
#elif defined(__GNUC__)
  info.compiler = "gcc " __VERSION__;
#else
  info.compiler = "unknown";
#endif
#ifdef NDEBUG
  info.debug = false;
#else
  info.debug = true;
#endif
  info.hardware_threads = static_cast<int>(std::thread::hardware_concurrency());
#ifdef DS3D_SIMD_LEVEL
  info.simd = DS3D_SIMD_LEVEL;
#else
  info.simd = "unknown";
#endif
  const char* isa[] = {
#ifdef __SSE2__
      "sse2",
#endif
#ifdef __AVX__
      "avx",
#endif
#ifdef __AVX2__
      "avx2",
#endif
#ifdef __FMA__
      "fma",
#endif
#ifdef __AVX512F__
      "avx512f",
#endif
#ifdef __ARM_NEON
      "neon",
#endif
      nullptr};
  for (const char* const* p = isa; *p != nullptr; ++p) {
    if (!info.simd_isa.empty()) info.simd_isa += ' ';
    info.simd_isa += *p;
  }
  info.eigen_max_align_bytes = EIGEN_MAX_ALIGN_BYTES;
  return info;
}

std::string build_info_string() {
  const BuildInfo i = build_info();
  return "ds3d " + i.ds3d_version + " (" + (i.debug ? "debug" : "release") + ", " + i.compiler +
         "; OpenCV " + i.opencv_version + ", Ceres " + i.ceres_version + ", Eigen " +
         i.eigen_version + "; SIMD " + i.simd + " [" + i.simd_isa + "]; " +
         std::to_string(i.hardware_threads) + " hardware threads)";
}

}  // namespace ds3d
