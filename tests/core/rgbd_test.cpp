// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d::depth_to_points against the golden 640x480 frame and the camera model.
#include "ds3d/preprocess/rgbd.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "support/depth_scene.hpp"
#include "support/preprocess_fixtures.hpp"

namespace {

using ds3d::PinholeCamera;

PinholeCamera fixture_camera(const std::filesystem::path& dir) {
  const auto j = ds3d::test::read_json(dir / "intrinsics.json");
  PinholeCamera c;
  c.width = static_cast<int>(j.at("width").as_int());
  c.height = static_cast<int>(j.at("height").as_int());
  c.fx = j.at("fx").as_number();
  c.fy = j.at("fy").as_number();
  c.cx = j.at("cx").as_number();
  c.cy = j.at("cy").as_number();
  c.depth_scale = j.at("depth_scale").as_number();
  return c;
}

std::vector<std::uint16_t> read_u16(const std::filesystem::path& p) {
  const std::string bytes = ds3d::test::read_file(p);
  std::vector<std::uint16_t> v(bytes.size() / 2);
  std::memcpy(v.data(), bytes.data(), v.size() * 2);
  return v;
}

void expect_close(const ds3d::Points3f& got, Eigen::Index gi, const ds3d::Points3f& want,
                  Eigen::Index wi) {
  const double z = want(wi, 2);
  for (int d = 0; d < 3; ++d) {
    ASSERT_LE(std::abs(double(got(gi, d)) - double(want(wi, d))), 1e-6 * z + 1e-7)
        << "point " << wi << " axis " << d;
  }
}

TEST(Rgbd, MatchesGoldenFrame) {
  const auto dir = ds3d::test::data_path("preprocess/depth_640x480");
  const PinholeCamera cam = fixture_camera(dir);
  const auto depth = read_u16(dir / "depth_u16.bin");
  ASSERT_EQ(depth.size(), 640U * 480U);
  const auto r = ds3d::depth_to_points(depth.data(), 640, 480, 640, cam);
  const auto meta = ds3d::test::read_json(dir / "case.json");
  ASSERT_EQ(r.points.rows(), meta.at("n_valid_pixels").as_int());
  EXPECT_EQ(r.num_invalid, 640U * 480U - static_cast<std::size_t>(r.points.rows()));
  EXPECT_TRUE(r.points.allFinite());
  // Golden rows v % 16 == 0, in order: our rows with those v, in order, must match one to one.
  const ds3d::Points3f want = ds3d::test::read_points_bin(dir / "expected_points_v16.bin");
  const auto want_pix = read_u16(dir / "expected_pixels_v16_u16.bin");
  Eigen::Index k = 0;
  for (Eigen::Index i = 0; i < r.points.rows(); ++i) {
    if (r.pixels(i, 1) % 16 != 0) continue;
    ASSERT_LT(k, want.rows());
    ASSERT_EQ(r.pixels(i, 0), want_pix[2 * static_cast<std::size_t>(k)]);
    ASSERT_EQ(r.pixels(i, 1), want_pix[2 * static_cast<std::size_t>(k) + 1]);
    expect_close(r.points, i, want, k);
    ++k;
  }
  EXPECT_EQ(k, want.rows());

  // Full golden frame when the shared fixtures are present.
  for (const auto& root : ds3d::test::preprocess_fixture_roots()) {
    const auto full = root / "depth_640x480" / "expected_points.bin";
    if (!std::filesystem::exists(full)) continue;
    const ds3d::Points3f all = ds3d::test::read_points_bin(full);
    const auto pix = read_u16(root / "depth_640x480" / "expected_pixels_u16.bin");
    ASSERT_EQ(all.rows(), r.points.rows());
    for (Eigen::Index i = 0; i < all.rows(); ++i) {
      ASSERT_EQ(r.pixels(i, 0), pix[2 * static_cast<std::size_t>(i)]);
      ASSERT_EQ(r.pixels(i, 1), pix[2 * static_cast<std::size_t>(i) + 1]);
      expect_close(r.points, i, all, i);
    }
  }
}

TEST(Rgbd, StrideRoiRangeAndEigenOverload) {
  const auto frame = ds3d::test::render_room(3);
  const PinholeCamera& cam = frame.camera;
  const Eigen::Map<const ds3d::DepthImageU16> img(frame.depth.data(), 480, 640);
  const auto full = ds3d::depth_to_points(img, cam);
  const auto raw = ds3d::depth_to_points(frame.depth.data(), 640, 480, 640, cam);
  EXPECT_EQ(full.points, raw.points);
  EXPECT_EQ(full.pixels, raw.pixels);
  // Row-major order, and each point reprojects to its pixel with z = d / scale.
  for (Eigen::Index i = 0; i < full.points.rows(); i += 997) {
    const auto u = full.pixels(i, 0);
    const auto v = full.pixels(i, 1);
    const double z =
        frame.depth[static_cast<std::size_t>(v) * 640 + static_cast<std::size_t>(u)] / 5000.0;
    EXPECT_NEAR(full.points(i, 2), z, 1e-6);
    const Eigen::Vector2d px = cam.project(full.points.row(i).cast<double>().transpose());
    EXPECT_NEAR(px.x(), u, 1e-3);
    EXPECT_NEAR(px.y(), v, 1e-3);
    if (i > 0) {
      EXPECT_TRUE(full.pixels(i - 1, 1) < v ||
                  (full.pixels(i - 1, 1) == v && full.pixels(i - 1, 0) < u));
    }
  }
  ds3d::DepthToPointsParams p;
  p.stride = 4;
  p.roi = {100, 50, 200, 120};
  p.min_depth = 1.0;
  p.max_depth = 3.0;
  const auto sub = ds3d::depth_to_points(img, cam, p);
  std::size_t expected = 0;
  std::size_t out_of_range = 0;
  std::size_t invalid = 0;
  for (int v = 50; v < 170; v += 4) {
    for (int u = 100; u < 300; u += 4) {
      const auto d = frame.depth[static_cast<std::size_t>(v) * 640 + static_cast<std::size_t>(u)];
      if (d == 0) {
        ++invalid;
      } else if (d / 5000.0 < 1.0 || d / 5000.0 > 3.0) {
        ++out_of_range;
      } else {
        ++expected;
      }
    }
  }
  EXPECT_EQ(static_cast<std::size_t>(sub.points.rows()), expected);
  EXPECT_EQ(sub.num_out_of_range, out_of_range);
  EXPECT_EQ(sub.num_invalid, invalid);
  for (Eigen::Index i = 0; i < sub.pixels.rows(); ++i) {
    EXPECT_EQ((sub.pixels(i, 0) - 100) % 4, 0);
    EXPECT_EQ((sub.pixels(i, 1) - 50) % 4, 0);
  }
}

TEST(Rgbd, FloatDepthSkipsNanZeroAndNegative) {
  PinholeCamera cam;
  cam.width = 4;
  cam.height = 2;
  cam.cx = 1.5;
  cam.cy = 0.5;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  // Row stride 5 (one padding element per row).
  const std::vector<float> d = {1.0F, 0.0F, nan, 2.0F, 9.0F, -1.0F, inf, 0.5F, 1.5F, 9.0F};
  const auto r = ds3d::depth_to_points(d.data(), 4, 2, 5, cam);
  ASSERT_EQ(r.points.rows(), 4);
  EXPECT_EQ(r.num_invalid, 4U);
  EXPECT_TRUE(r.points.allFinite());
  EXPECT_EQ(r.pixels(1, 0), 3);
  EXPECT_EQ(r.pixels(1, 1), 0);
  EXPECT_NEAR(r.points(1, 0), (3 - 1.5) * 2.0 / 525.0, 1e-7);
  EXPECT_NEAR(r.points(3, 2), 1.5, 1e-7);
}

// A 64x48 camera without distortion.
PinholeCamera small_camera() {
  PinholeCamera cam;
  cam.width = 64;
  cam.height = 48;
  cam.fx = cam.fy = 50;
  cam.cx = 31.5;
  cam.cy = 23.5;
  return cam;
}

TEST(Rgbd, DistortionUsesUndistortedRays) {
  PinholeCamera cam = small_camera();
  cam.k1 = -0.2;
  cam.p1 = 0.001;
  std::vector<std::uint16_t> d(64 * 48, 10000);
  const auto r = ds3d::depth_to_points(d.data(), 64, 48, 64, cam);
  const auto rays = ds3d::make_pixel_rays(cam);
  ds3d::DepthToPointsParams p;
  p.rays = &rays;
  const auto r2 = ds3d::depth_to_points(d.data(), 64, 48, 64, cam, p);
  EXPECT_EQ(r.points, r2.points);
  for (Eigen::Index i = 0; i < r.points.rows(); i += 37) {
    const Eigen::Vector3d want = cam.back_project(r.pixels(i, 0), r.pixels(i, 1), 2.0);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(r.points(i, k), want[k], 1e-6);
    const Eigen::Vector2d px = cam.project(want);
    EXPECT_NEAR(px.x(), r.pixels(i, 0), 1e-6);
  }
  p.undistort = false;
  const auto plain = ds3d::depth_to_points(d.data(), 64, 48, 64, cam, p);
  EXPECT_NEAR(plain.points(0, 0), (0 - 31.5) / 50.0 * 2.0, 1e-6);
  EXPECT_GT(std::abs(plain.points(0, 0) - r.points(0, 0)), 1e-3);
}

// PixelRayCache: the same table as make_pixel_rays, built again only for another camera.
TEST(Rgbd, PixelRayCacheRebuildsOnlyForAnotherCamera) {
  PinholeCamera cam = small_camera();
  ds3d::PixelRayCache cache;
  EXPECT_EQ(cache.get(cam), nullptr) << "no table without distortion";
  cam.k1 = -0.2;
  const ds3d::PixelRays* a = cache.get(cam);
  ASSERT_NE(a, nullptr);
  const auto want = ds3d::make_pixel_rays(cam);
  EXPECT_EQ(a->x, want.x);
  EXPECT_EQ(a->y, want.y);
  const std::vector<double> first_x = a->x;
  cam.depth_scale = 1000.0;  // not part of the rays
  EXPECT_EQ(cache.get(cam), a);
  EXPECT_EQ(cache.get(cam)->x, first_x);
  cam.k2 = 0.05;
  const ds3d::PixelRays* b = cache.get(cam);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(b->x, ds3d::make_pixel_rays(cam).x);
  EXPECT_NE(b->x, first_x);
  cam.width = 32;
  cam.cx = 15.5;
  EXPECT_EQ(cache.get(cam)->width, 32);
  // An invalid camera throws and leaves the cached table as it was.
  PinholeCamera bad = cam;
  bad.fx = -1.0;
  EXPECT_THROW((void)cache.get(bad), ds3d::InvalidArgument);
  EXPECT_EQ(cache.get(cam)->width, 32);
  // depth_to_points with the cached table gives the same points as without.
  std::vector<std::uint16_t> d(32 * 48, 10000);
  ds3d::DepthToPointsParams p;
  p.rays = cache.get(cam);
  EXPECT_EQ(ds3d::depth_to_points(d.data(), 32, 48, 32, cam, p).points,
            ds3d::depth_to_points(d.data(), 32, 48, 32, cam).points);
}

TEST(Rgbd, RejectsBadInput) {
  PinholeCamera cam;
  std::vector<std::uint16_t> d(640 * 480, 1000);
  EXPECT_THROW((void)ds3d::depth_to_points(d.data(), 320, 480, 640, cam), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::depth_to_points(d.data(), 640, 480, 600, cam), ds3d::InvalidArgument);
  EXPECT_THROW(
      (void)ds3d::depth_to_points(static_cast<const std::uint16_t*>(nullptr), 640, 480, 640, cam),
      ds3d::InvalidArgument);
  ds3d::DepthToPointsParams p;
  p.stride = 0;
  EXPECT_THROW((void)ds3d::depth_to_points(d.data(), 640, 480, 640, cam, p), ds3d::InvalidArgument);
  p = {};
  p.roi = {600, 0, 100, 0};
  EXPECT_THROW((void)ds3d::depth_to_points(d.data(), 640, 480, 640, cam, p), ds3d::InvalidArgument);
  p = {};
  p.min_depth = 2;
  p.max_depth = 1;
  EXPECT_THROW((void)ds3d::depth_to_points(d.data(), 640, 480, 640, cam, p), ds3d::InvalidArgument);
  cam.fx = -1;
  try {
    (void)ds3d::depth_to_points(d.data(), 640, 480, 640, cam);
    FAIL();
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("ds3d::depth_to_points: fx"), std::string::npos);
  }
}

}  // namespace
