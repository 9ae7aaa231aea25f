// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/build_info.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>

#include "ds3d/version.hpp"

TEST(BuildInfo, ReportsVersions) {
  const ds3d::BuildInfo info = ds3d::build_info();
  EXPECT_EQ(info.ds3d_version, ds3d::kVersion);
  EXPECT_EQ(info.opencv_version.substr(0, 2), "4.");
  EXPECT_FALSE(info.ceres_version.empty());
  EXPECT_FALSE(info.eigen_version.empty());
  EXPECT_NE(ds3d::build_info_string().find(info.opencv_version), std::string::npos);
}

TEST(BuildInfo, SimdLevelMatchesThisTranslationUnit) {
  const ds3d::BuildInfo info = ds3d::build_info();
  ASSERT_TRUE(info.simd == "avx2" || info.simd == "none") << info.simd;
  // DS3D_SIMD applies the same flags to every compiled target, tests included.
#if defined(__AVX2__) && defined(__FMA__)
  EXPECT_EQ(info.simd, "avx2");
#else
  EXPECT_EQ(info.simd, "none");
#endif
  if (info.simd == "avx2") {
    EXPECT_NE(info.simd_isa.find("avx2"), std::string::npos) << info.simd_isa;
    EXPECT_NE(info.simd_isa.find("fma"), std::string::npos) << info.simd_isa;
  }
  // The Eigen ABI guard reaches consumers through ds3d::core and matches the library's.
  EXPECT_EQ(info.eigen_max_align_bytes, 16);
  EXPECT_EQ(info.eigen_max_align_bytes, EIGEN_MAX_ALIGN_BYTES);
  EXPECT_NE(ds3d::build_info_string().find("SIMD " + info.simd), std::string::npos);
}
