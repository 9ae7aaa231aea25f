// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/camera.hpp"

#include <gtest/gtest.h>

namespace {

ds3d::PinholeCamera tum_fr1() {
  ds3d::PinholeCamera c;
  c.fx = 517.306408;
  c.fy = 516.469215;
  c.cx = 318.643040;
  c.cy = 255.313989;
  c.k1 = 0.262383;
  c.k2 = -0.953104;
  c.p1 = -0.005358;
  c.p2 = 0.002628;
  c.k3 = 1.163314;
  return c;
}

TEST(Camera, ProjectBackProjectRoundTripWithoutDistortion) {
  const ds3d::PinholeCamera cam;
  const Eigen::Vector3d p(0.3, -0.2, 1.7);
  const Eigen::Vector2d uv = cam.project(p);
  EXPECT_NEAR(uv.x(), 525.0 * 0.3 / 1.7 + 319.5, 1e-12);
  EXPECT_TRUE(cam.back_project(uv.x(), uv.y(), 1.7).isApprox(p, 1e-12));
}

TEST(Camera, UndistortInvertsDistortOverTheImage) {
  const ds3d::PinholeCamera cam = tum_fr1();
  ASSERT_TRUE(cam.has_distortion());
  for (double u = 0; u < 640; u += 80) {
    for (double v = 0; v < 480; v += 80) {
      const Eigen::Vector3d p = cam.back_project(u, v, 2.0);
      const Eigen::Vector2d uv = cam.project(p);
      EXPECT_NEAR(uv.x(), u, 1e-3) << u << "," << v;
      EXPECT_NEAR(uv.y(), v, 1e-3) << u << "," << v;
    }
  }
}

TEST(Camera, ValidateNamesTheField) {
  ds3d::PinholeCamera cam;
  cam.fy = -1;
  try {
    cam.validate("ds3d::f");
    FAIL();
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_STREQ(e.what(), "ds3d::f: fy must be finite and > 0 (got -1)");
  }
  cam = {};
  cam.depth_scale = 0;
  EXPECT_THROW(cam.validate(), ds3d::InvalidArgument);
  cam = {};
  EXPECT_NO_THROW(cam.validate());
}

TEST(Camera, InImage) {
  const ds3d::PinholeCamera cam;
  EXPECT_TRUE(cam.in_image(0, 0));
  EXPECT_TRUE(cam.in_image(639.4, 479.4));
  EXPECT_FALSE(cam.in_image(639.6, 10));
  EXPECT_FALSE(cam.in_image(5, 5, 10));
}

}  // namespace
