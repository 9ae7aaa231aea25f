// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/errors.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace {

TEST(Errors, HierarchyMapsToStdTypes) {
  EXPECT_THROW(throw ds3d::InvalidArgument("x"), std::invalid_argument);
  EXPECT_THROW(throw ds3d::IoError("x"), std::runtime_error);
  EXPECT_THROW(throw ds3d::NumericalError("x"), std::runtime_error);
}

TEST(Errors, CheckFormatsFunctionParameterAndValue) {
  const double leaf = -0.1;
  try {
    DS3D_CHECK(leaf > 0, "ds3d::voxel_grid: leaf_size must be > 0 (got ", leaf, ")");
    FAIL() << "DS3D_CHECK did not throw";
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_STREQ(e.what(), "ds3d::voxel_grid: leaf_size must be > 0 (got -0.10000000000000001)");
  }
}

TEST(Errors, CheckPassesWithoutEvaluatingMessage) {
  int evaluated = 0;
  auto side_effect = [&] {
    ++evaluated;
    return "msg";
  };
  DS3D_CHECK(true, side_effect());
  EXPECT_EQ(evaluated, 0);
}

TEST(Errors, CheckAsThrowsRequestedType) {
  EXPECT_THROW(DS3D_CHECK_AS(ds3d::IoError, false, "file ", "a.txt"), ds3d::IoError);
  EXPECT_THROW(DS3D_CHECK_AS(ds3d::NumericalError, 1 > 2, "nan"), ds3d::NumericalError);
  EXPECT_NO_THROW(DS3D_CHECK_AS(ds3d::IoError, true, "unused"));
}

}  // namespace
