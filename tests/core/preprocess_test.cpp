// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d::preprocess: the composition equals running the stages by hand, on a rendered room.
#include "ds3d/preprocess/preprocess.hpp"

#include <gtest/gtest.h>

#include "support/depth_scene.hpp"

namespace {

TEST(Preprocess, EqualsTheStagesRunByHand) {
  const auto frame = ds3d::test::render_room(12);
  const auto& cam = frame.camera;
  const ds3d::PreprocessParams params;
  const auto r = ds3d::preprocess(frame.depth.data(), 640, 480, 640, cam, params);

  const auto pts = ds3d::depth_to_points(frame.depth.data(), 640, 480, 640, cam, params.depth);
  const auto vox = ds3d::voxel_grid(pts.points, params.voxel);
  const auto plane = ds3d::ransac_plane(vox.centroids, params.ground);
  ASSERT_TRUE(plane.found);
  ASSERT_TRUE(r.ground_found);
  EXPECT_EQ(r.ground_plane, plane.plane);
  // The floor is y = 1.2 in the camera frame: normal ~ -y, d ~ 1.2.
  EXPECT_GT(-plane.plane[1], 0.99);
  EXPECT_NEAR(plane.plane[3], 1.2, 0.03);
  std::vector<bool> is_ground(static_cast<std::size_t>(vox.centroids.rows()), false);
  for (const auto i : plane.inliers) is_ground[i] = true;
  ds3d::Points3f rest(static_cast<Eigen::Index>(is_ground.size() - plane.inliers.size()), 3);
  std::vector<std::uint32_t> rest_row;
  for (std::size_t i = 0; i < is_ground.size(); ++i) {
    if (is_ground[i]) continue;
    rest.row(static_cast<Eigen::Index>(rest_row.size())) =
        vox.centroids.row(static_cast<Eigen::Index>(i));
    rest_row.push_back(static_cast<std::uint32_t>(i));
  }
  const auto kept = ds3d::remove_radius_outliers(rest, params.outlier);

  EXPECT_EQ(r.num_input, static_cast<std::size_t>(pts.points.rows()));
  EXPECT_EQ(r.num_voxels, static_cast<std::size_t>(vox.centroids.rows()));
  EXPECT_EQ(r.num_ground, plane.inliers.size());
  EXPECT_EQ(r.num_outliers, rest_row.size() - kept.kept.size());
  ASSERT_EQ(static_cast<std::size_t>(r.points.rows()), kept.kept.size());
  EXPECT_GT(r.points.rows(), 1000);  // ~4k detector points with the default 0.1 m leaf
  EXPECT_LT(r.points.rows(), 10000);
  EXPECT_TRUE(r.points.allFinite());
  for (std::size_t i = 0; i < kept.kept.size(); ++i) {
    const auto row = rest_row[kept.kept[i]];
    EXPECT_EQ(r.voxel[i], row);
    EXPECT_EQ(r.points.row(static_cast<Eigen::Index>(i)), vox.centroids.row(row));
    EXPECT_EQ(r.source[i], vox.representative[row]);
    EXPECT_EQ(r.pixels.row(static_cast<Eigen::Index>(i)), pts.pixels.row(r.source[i]));
  }
  EXPECT_GE(r.ms_voxel, 0.0);
}

TEST(Preprocess, SameResultForAnyThreadCountAndCloudInput) {
  const auto frame = ds3d::test::render_room(13);
  ds3d::PreprocessParams p;
  const auto r1 = ds3d::preprocess(frame.depth.data(), 640, 480, 640, frame.camera, p);
  p.num_threads = 3;
  const auto r3 = ds3d::preprocess(frame.depth.data(), 640, 480, 640, frame.camera, p);
  EXPECT_EQ(r1.points, r3.points);
  EXPECT_EQ(r1.source, r3.source);
  EXPECT_EQ(r1.pixels, r3.pixels);
  const auto pts = ds3d::depth_to_points(frame.depth.data(), 640, 480, 640, frame.camera, p.depth);
  const auto rc = ds3d::preprocess_cloud(pts.points, p);
  EXPECT_EQ(rc.points, r1.points);
  EXPECT_EQ(rc.source, r1.source);
  EXPECT_EQ(rc.pixels.rows(), 0);
}

TEST(Preprocess, StagesCanBeSwitchedOffAndEmptyFramesWork) {
  const auto frame = ds3d::test::render_room(14);
  ds3d::PreprocessParams p;
  p.remove_ground = false;
  p.remove_outliers = false;
  const auto r = ds3d::preprocess(frame.depth.data(), 640, 480, 640, frame.camera, p);
  EXPECT_EQ(static_cast<std::size_t>(r.points.rows()), r.num_voxels);
  EXPECT_FALSE(r.ground_found);
  const std::vector<std::uint16_t> zeros(640 * 480, 0);
  const auto e = ds3d::preprocess(zeros.data(), 640, 480, 640, frame.camera);
  EXPECT_EQ(e.points.rows(), 0);
  EXPECT_EQ(e.num_input, 0U);
  EXPECT_FALSE(e.ground_found);
}

TEST(Preprocess, RejectsBadParams) {
  const auto frame = ds3d::test::render_room(15);
  ds3d::PreprocessParams p;
  p.voxel.leaf_size = -1.0;
  EXPECT_THROW((void)ds3d::preprocess(frame.depth.data(), 640, 480, 640, frame.camera, p),
               ds3d::InvalidArgument);
  p = {};
  p.num_threads = -1;
  EXPECT_THROW((void)ds3d::preprocess(frame.depth.data(), 640, 480, 640, frame.camera, p),
               ds3d::InvalidArgument);
  p = {};
  p.min_ground_fraction = 2;
  EXPECT_THROW((void)ds3d::preprocess(frame.depth.data(), 640, 480, 640, frame.camera, p),
               ds3d::InvalidArgument);
  p = {};
  p.outlier.radius = 0;
  EXPECT_THROW((void)ds3d::preprocess(frame.depth.data(), 640, 480, 640, frame.camera, p),
               ds3d::InvalidArgument);
}

}  // namespace
