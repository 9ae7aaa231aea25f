// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/cloud.hpp"

#include <gtest/gtest.h>

#include <array>
#include <limits>
#include <vector>

#include "support/synthetic.hpp"

namespace {

struct UserPoint {
  float x, y, z;
  unsigned char r, g, b;
};

}  // namespace

template <>
struct ds3d::PointCloudTraits<std::vector<UserPoint>> {
  static std::size_t size(const std::vector<UserPoint>& c) { return c.size(); }
  static Eigen::Vector3f point(const std::vector<UserPoint>& c, std::size_t i) {
    return {c[i].x, c[i].y, c[i].z};
  }
};
static_assert(ds3d::PointCloud<std::vector<UserPoint>>);
static_assert(!ds3d::PointCloud<int>);

namespace {

ds3d::Points3f reference_points() {
  ds3d::test::Rng rng(7);
  return ds3d::test::uniform_box(50, {-1, -2, 0}, {1, 2, 3}, rng);
}

template <class C>
C convert(const ds3d::Points3f& p);
template <>
ds3d::Points3f convert(const ds3d::Points3f& p) {
  return p;
}
template <>
ds3d::Points3d convert(const ds3d::Points3f& p) {
  return p.cast<double>();
}
template <>
std::vector<Eigen::Vector3f> convert(const ds3d::Points3f& p) {
  std::vector<Eigen::Vector3f> v;
  for (Eigen::Index i = 0; i < p.rows(); ++i) v.emplace_back(p.row(i).transpose());
  return v;
}
template <>
std::vector<std::array<float, 3>> convert(const ds3d::Points3f& p) {
  std::vector<std::array<float, 3>> v;
  for (Eigen::Index i = 0; i < p.rows(); ++i) v.push_back({p(i, 0), p(i, 1), p(i, 2)});
  return v;
}
template <>
std::vector<UserPoint> convert(const ds3d::Points3f& p) {
  std::vector<UserPoint> v;
  for (Eigen::Index i = 0; i < p.rows(); ++i) v.push_back({p(i, 0), p(i, 1), p(i, 2), 1, 2, 3});
  return v;
}

template <class C>
class CloudTraits : public ::testing::Test {};
using CloudTypes = ::testing::Types<ds3d::Points3f, ds3d::Points3d, std::vector<Eigen::Vector3f>,
                                    std::vector<std::array<float, 3>>, std::vector<UserPoint>>;
TYPED_TEST_SUITE(CloudTraits, CloudTypes);

TYPED_TEST(CloudTraits, ReadsEveryPointInOrder) {
  const ds3d::Points3f ref = reference_points();
  const TypeParam c = convert<TypeParam>(ref);
  ASSERT_EQ(ds3d::cloud::size(c), static_cast<std::size_t>(ref.rows()));
  for (std::size_t i = 0; i < ds3d::cloud::size(c); ++i) {
    EXPECT_EQ(ds3d::cloud::point(c, i), ref.row(static_cast<Eigen::Index>(i)).transpose());
  }
  EXPECT_EQ(ds3d::cloud::to_points3f(c), ref);
}

TEST(Cloud, RefAdaptorSharesMemory) {
  const ds3d::Points3f ref = reference_points();
  const Eigen::Ref<const ds3d::Points3f> view(ref);
  EXPECT_EQ(view.data(), ref.data());
  EXPECT_EQ(ds3d::cloud::point(view, 3), ref.row(3).transpose());
}

TEST(Cloud, IsFinite) {
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  EXPECT_TRUE(ds3d::cloud::is_finite({0, 1, 2}));
  EXPECT_FALSE(ds3d::cloud::is_finite({kNan, 1, 2}));
  EXPECT_FALSE(ds3d::cloud::is_finite({0, -kInf, 2}));
  EXPECT_FALSE(ds3d::cloud::is_finite({0, 1, kInf}));
}

TEST(Cloud, EmptyCloud) {
  const ds3d::Points3f empty(0, 3);
  EXPECT_EQ(ds3d::cloud::size(empty), 0U);
  EXPECT_EQ(ds3d::cloud::to_points3f(empty).rows(), 0);
}

}  // namespace
