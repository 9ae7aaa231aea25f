// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/build_info.hpp"

#include <gtest/gtest.h>

#include "ds3d/version.hpp"

TEST(BuildInfo, ReportsVersions) {
  const ds3d::BuildInfo info = ds3d::build_info();
  EXPECT_EQ(info.ds3d_version, ds3d::kVersion);
  EXPECT_EQ(info.opencv_version.substr(0, 2), "4.");
  EXPECT_FALSE(info.ceres_version.empty());
  EXPECT_FALSE(info.eigen_version.empty());
  EXPECT_NE(ds3d::build_info_string().find(info.opencv_version), std::string::npos);
}
