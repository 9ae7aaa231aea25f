// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/htx/part_a2_targets.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "support/synthetic.hpp"

namespace {

ds3d::Box3 make_box(Eigen::Vector3f c, Eigen::Vector3f s, float yaw) {
  ds3d::Box3 b;
  b.centre = c;
  b.size = s;
  b.yaw = yaw;
  return b;
}

TEST(PartA2Targets, EmptyInput) {
  const ds3d::Points3f pts(0, 3);
  const std::vector<ds3d::Box3> boxes;
  const auto t = ds3d::part_a2_targets(pts, boxes);
  EXPECT_TRUE(t.label.empty());
  EXPECT_EQ(t.part.rows(), 0);
}

TEST(PartA2Targets, CentreIsHalfAndAxesFollowTheHeading) {
  // theta = pi/2: the length axis points along -Y (spec §2).
  const auto b =
      make_box({1.0F, 2.0F, 0.5F}, {2.0F, 1.0F, 1.0F}, static_cast<float>(std::numbers::pi / 2));
  ds3d::Points3f pts(4, 3);
  pts << 1.0F, 2.0F, 0.5F,  // centre
      1.0F, 1.5F, 0.5F,     // 0.5 m along -Y = along the length axis: x_local = +0.5
      1.25F, 2.0F, 0.5F,    // 0.25 m along +X = local +y
      1.0F, 2.0F, 0.75F;    // 0.25 m up
  const auto t = ds3d::part_a2_targets(pts, std::vector<ds3d::Box3>{b});
  ASSERT_EQ(t.label, (std::vector<std::int8_t>{1, 1, 1, 1}));
  EXPECT_TRUE(t.part.row(0).isApprox(Eigen::RowVector3f(0.5F, 0.5F, 0.5F), 1e-6F));
  EXPECT_NEAR(t.part(1, 0), 0.75F, 1e-6F);  // 0.5 / 2 + 0.5
  EXPECT_NEAR(t.part(1, 1), 0.5F, 1e-6F);
  EXPECT_NEAR(t.part(2, 0), 0.5F, 1e-6F);
  EXPECT_NEAR(t.part(2, 1), 0.75F, 1e-6F);  // 0.25 / 1 + 0.5
  EXPECT_NEAR(t.part(3, 2), 0.75F, 1e-6F);
}

TEST(PartA2Targets, IgnoreBandAndBackground) {
  const auto b = make_box({0, 0, 0}, {1.0F, 1.0F, 1.0F}, 0.0F);
  ds3d::Points3f pts(3, 3);
  pts << 0.55F, 0.0F, 0.0F,  // outside the box, inside the box grown by 0.2 (half 0.6)
      0.65F, 0.0F, 0.0F,     // outside both
      0.0F, 0.0F, 0.5F;      // on the top face: inclusive in z
  const auto t = ds3d::part_a2_targets(pts, std::vector<ds3d::Box3>{b});
  EXPECT_EQ(t.label, (std::vector<std::int8_t>{-1, 0, 1}));
  EXPECT_EQ(t.box_index, (std::vector<std::int32_t>{-1, -1, 0}));
  EXPECT_TRUE(t.part.row(0).isZero());
  EXPECT_NEAR(t.part(2, 2), 1.0F, 1e-6F);
}

TEST(PartA2Targets, FirstBoxWinsOnOverlap) {
  const std::vector<ds3d::Box3> boxes{make_box({0, 0, 0}, {1, 1, 1}, 0.0F),
                                      make_box({0.2F, 0, 0}, {1, 1, 1}, 0.3F)};
  ds3d::Points3f pts(1, 3);
  pts << 0.1F, 0.0F, 0.0F;
  const auto t = ds3d::part_a2_targets(pts, boxes);
  EXPECT_EQ(t.box_index[0], 0);
}

TEST(PartA2Targets, RejectsBadParams) {
  const ds3d::Points3f pts = ds3d::Points3f::Zero(2, 3);
  EXPECT_THROW(
      (void)ds3d::part_a2_targets(pts, std::vector<ds3d::Box3>{make_box({0, 0, 0}, {0, 1, 1}, 0)}),
      ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::part_a2_targets(
                   pts, std::vector<ds3d::Box3>{make_box({0, 0, 0}, {1, 1, 1}, std::nanf(""))}),
               ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::part_a2_targets(pts, std::vector<ds3d::Box3>{}, {.extra_width = -1.0}),
               ds3d::InvalidArgument);
}

TEST(PartA2Targets, NonFiniteInput) {
  ds3d::Points3f pts = ds3d::Points3f::Zero(3, 3);
  pts(1, 0) = std::numeric_limits<float>::quiet_NaN();
  const std::vector<ds3d::Box3> boxes{make_box({0, 0, 0}, {1, 1, 1}, 0.0F)};
  const auto t = ds3d::part_a2_targets(pts, boxes);
  EXPECT_EQ(t.num_non_finite, 1U);
  EXPECT_EQ(t.label[1], 0);
  EXPECT_TRUE(t.part.allFinite());
  EXPECT_THROW((void)ds3d::part_a2_targets(pts, boxes, {.on_non_finite = ds3d::NonFinite::kThrow}),
               ds3d::InvalidArgument);
}

// Brute force with an explicit rotation matrix (corners convention) instead of to_local.
TEST(PartA2Targets, MatchesBruteForceOnRandomBoxes) {
  ds3d::test::Rng rng(7);
  std::vector<ds3d::Box3> boxes;
  for (int k = 0; k < 5; ++k) {
    boxes.push_back(make_box(Eigen::Vector3f(static_cast<float>(rng.uniform(-2, 2)),
                                             static_cast<float>(rng.uniform(-2, 2)),
                                             static_cast<float>(rng.uniform(0, 1))),
                             Eigen::Vector3f(static_cast<float>(rng.uniform(0.3, 2)),
                                             static_cast<float>(rng.uniform(0.3, 2)),
                                             static_cast<float>(rng.uniform(0.3, 2))),
                             static_cast<float>(rng.uniform(-3.14, 3.14))));
  }
  const ds3d::Points3f pts = ds3d::test::uniform_box(3000, {-3, -3, -1}, {3, 3, 2}, rng);
  const auto t = ds3d::part_a2_targets(pts, boxes);
  int fg = 0;
  for (Eigen::Index i = 0; i < pts.rows(); ++i) {
    int owner = -1;
    for (std::size_t k = 0; k < boxes.size() && owner < 0; ++k) {
      const auto& b = boxes[k];
      // Rz(-yaw) maps local to world, so its transpose maps world to local.
      Eigen::Matrix3d rz_minus = Eigen::Matrix3d::Identity();
      const double c = std::cos(static_cast<double>(b.yaw)),
                   s = std::sin(static_cast<double>(b.yaw));
      rz_minus << c, s, 0, -s, c, 0, 0, 0, 1;
      const Eigen::Vector3d l =
          rz_minus.transpose() * (pts.row(i).transpose().cast<double>() - b.centre.cast<double>());
      if (std::abs(l.x()) < b.size.x() / 2.0 && std::abs(l.y()) < b.size.y() / 2.0 &&
          std::abs(l.z()) <= b.size.z() / 2.0) {
        owner = static_cast<int>(k);
        const Eigen::Vector3d expect = l.cwiseQuotient(b.size.cast<double>()).array() + 0.5;
        EXPECT_TRUE(t.part.row(i).transpose().cast<double>().isApprox(expect, 1e-6));
        EXPECT_TRUE((t.part.row(i).array() >= 0.0F).all() && (t.part.row(i).array() <= 1.0F).all());
      }
    }
    EXPECT_EQ(t.box_index[static_cast<std::size_t>(i)], owner);
    fg += owner >= 0;
  }
  EXPECT_GT(fg, 50);  // the scene really exercises the foreground branch
}

TEST(Box3, CornersAabbAndLocalFrameAgree) {
  const auto b = make_box({1.0F, -2.0F, 0.5F}, {2.0F, 1.0F, 0.6F}, 0.7F);
  const auto corners = ds3d::box::corners(b);
  const auto hull = ds3d::box::aabb(b);
  Eigen::Vector3d lo = corners[0], hi = corners[0];
  for (const auto& c : corners) {
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
    // every corner sits at (+-dx/2, +-dy/2, +-dz/2) in the box frame
    const Eigen::Vector3d l = ds3d::box::to_local(b, c);
    EXPECT_NEAR(std::abs(l.x()), 1.0, 1e-6);
    EXPECT_NEAR(std::abs(l.y()), 0.5, 1e-6);
    EXPECT_NEAR(std::abs(l.z()), 0.3, 1e-6);
  }
  EXPECT_TRUE(lo.isApprox(hull[0], 1e-9));
  EXPECT_TRUE(hi.isApprox(hull[1], 1e-9));
  EXPECT_DOUBLE_EQ(ds3d::box::aabb_iou(b, b), 1.0);
  auto far = b;
  far.centre.x() += 10.0F;
  EXPECT_DOUBLE_EQ(ds3d::box::aabb_iou(b, far), 0.0);
}

}  // namespace
