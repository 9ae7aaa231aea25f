// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d::ransac_plane against the golden planes (fixture README tolerances) and edge cases.
#include "ds3d/preprocess/ransac_plane.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "support/preprocess_fixtures.hpp"
#include "support/synthetic.hpp"

namespace {

using ds3d::Points3f;
using ds3d::RansacPlaneParams;

/// Inliers of `plane` (normalised here) with the strict < t test in double over finite points.
std::vector<std::uint32_t> inliers_of(const Points3f& p, Eigen::Vector4d plane, double t) {
  plane /= plane.head<3>().norm();
  std::vector<std::uint32_t> out;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    if (!p.row(i).allFinite()) continue;
    const double d = plane.head<3>().dot(p.row(i).cast<double>().transpose()) + plane[3];
    if (std::abs(d) < t) out.push_back(static_cast<std::uint32_t>(i));
  }
  return out;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double c = std::abs(a.normalized().dot(b.normalized()));
  return std::acos(std::min(1.0, c)) * 180.0 / 3.14159265358979323846;
}

TEST(RansacPlane, MatchesEveryGoldenFixture) {
  int checked = 0;
  for (const auto& root : ds3d::test::preprocess_fixture_roots()) {
    for (const auto& dir : ds3d::test::preprocess_cases(root)) {
      const auto meta = ds3d::test::read_json(dir / "case.json");
      if (!meta.at("outputs").contains("plane")) continue;
      const auto& gold = meta.at("outputs").at("plane");
      const Points3f pts = ds3d::test::read_points_bin(dir / "input.bin");
      if (gold.is_null()) {  // no golden plane; the empty case must say "no plane", no crash
        if (meta.at("n_finite").as_int() >= 3) continue;
        const auto r = ds3d::ransac_plane(pts);
        EXPECT_FALSE(r.found);
        EXPECT_TRUE(r.inliers.empty());
        continue;
      }
      const double t = gold.at("threshold").as_number();
      const Eigen::Vector3d gn(gold.at("plane").at(0).as_number(),
                               gold.at("plane").at(1).as_number(),
                               gold.at("plane").at(2).as_number());
      const auto golden_count = static_cast<double>(gold.at("inlier_count").as_int());
      for (const std::uint64_t seed : {0U, 1U, 2U}) {
        RansacPlaneParams p;
        p.distance_threshold = t;
        p.max_iterations = 1000;
        p.seed = seed;
        const auto r = ds3d::ransac_plane(pts, p);
        ASSERT_TRUE(r.found) << dir;
        EXPECT_NEAR(r.plane.head<3>().norm(), 1.0, 1e-12);
        EXPECT_TRUE(r.plane.allFinite());
        const auto inl = inliers_of(pts, r.plane, t);
        EXPECT_GE(static_cast<double>(inl.size()), 0.97 * golden_count) << dir << " seed " << seed;
        EXPECT_LE(angle_deg(r.plane.head<3>(), gn), 2.0) << dir << " seed " << seed;
        EXPECT_EQ(r.inliers, inl) << "returned inliers must be those of the returned plane";
      }
      ++checked;
    }
  }
  EXPECT_GE(checked, 3);
}

TEST(RansacPlane, FewerThanThreeFinitePointsIsNoPlane) {
  Points3f p(4, 3);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  p << 0, 0, 0, 1, 0, 0, nan, 0, 0, 0, nan, 1;
  const auto r = ds3d::ransac_plane(p);
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.num_non_finite, 2U);
  EXPECT_TRUE(r.plane.isZero());
  EXPECT_FALSE(ds3d::ransac_plane(Points3f(0, 3)).found);
}

TEST(RansacPlane, CollinearPointsAreNoPlane) {
  Points3f p(20, 3);
  for (Eigen::Index i = 0; i < 20; ++i)
    p.row(i) << static_cast<float>(i), 2.0F * static_cast<float>(i), 0.5F;
  const auto r = ds3d::ransac_plane(p, {.max_iterations = 50});
  EXPECT_FALSE(r.found);
}

TEST(RansacPlane, ExactPlaneWithOutliersAndNonFinite) {
  ds3d::test::Rng rng(31);
  Points3f p(3000, 3);
  p.topRows(2000) = ds3d::test::plane_points(2000, 2.0, 0.002, rng);
  p.bottomRows(1000) = ds3d::test::uniform_box(1000, {-2, -2, 0.2}, {2, 2, 2}, rng);
  p(5, 0) = std::numeric_limits<float>::quiet_NaN();
  p(2500, 2) = -std::numeric_limits<float>::infinity();
  const auto r = ds3d::ransac_plane(p, {.distance_threshold = 0.01});
  ASSERT_TRUE(r.found);
  EXPECT_LE(angle_deg(r.plane.head<3>(), {0, 0, 1}), 0.5);
  EXPECT_GT(r.plane[2], 0.0);  // sign convention: largest component positive
  EXPECT_GE(r.inliers.size(), 1990U);
  EXPECT_EQ(r.num_non_finite, 2U);
  for (const auto i : r.inliers) EXPECT_NE(i, 5U);
  EXPECT_LT(r.iterations, 1000U);  // adaptive stop with 2/3 inliers needs ~20 iterations
}

TEST(RansacPlane, NormalPriorPicksTheFloorOverALargerWall) {
  ds3d::test::Rng rng(41);
  // Wall x = 0 with 3000 points, floor y = 1 (camera y down) with 1500 points.
  Points3f wall = ds3d::test::plane_points(3000, 2.0, 0.002, rng);
  wall.col(0).swap(wall.col(2));  // plane x = 0
  Points3f floor = ds3d::test::plane_points(1500, 2.0, 0.002, rng);
  floor.col(1).swap(floor.col(2));  // plane y = 0
  floor.col(1).array() += 1.0F;
  Points3f p(4500, 3);
  p << wall, floor;
  const auto any = ds3d::ransac_plane(p);
  ASSERT_TRUE(any.found);
  EXPECT_LE(angle_deg(any.plane.head<3>(), {1, 0, 0}), 1.0);
  RansacPlaneParams prior;
  prior.normal_prior = {0, -1, 0};
  prior.max_angle_deg = 20;
  const auto ground = ds3d::ransac_plane(p, prior);
  ASSERT_TRUE(ground.found);
  EXPECT_LE(angle_deg(ground.plane.head<3>(), {0, 1, 0}), 1.0);
  EXPECT_LT(ground.plane[1], 0.0);          // oriented along the prior
  EXPECT_NEAR(ground.plane[3], 1.0, 0.01);  // -y + d = 0 at y = 1
  EXPECT_GE(ground.inliers.size(), 1490U);
}

TEST(RansacPlane, OriginAbovePicksTheFloorNotALargerCeiling) {
  ds3d::test::Rng rng(43);
  Points3f ceiling = ds3d::test::plane_points(3000, 2.0, 0.002, rng);
  ceiling.col(1).swap(ceiling.col(2));
  ceiling.col(1).array() -= 1.4F;  // y = -1.4: above the camera (y points down)
  Points3f floor = ds3d::test::plane_points(1500, 2.0, 0.002, rng);
  floor.col(1).swap(floor.col(2));
  floor.col(1).array() += 1.2F;  // y = 1.2: below the camera
  Points3f p(4500, 3);
  p << ceiling, floor;
  RansacPlaneParams prior;
  prior.normal_prior = {0, -1, 0};
  const auto either = ds3d::ransac_plane(p, prior);
  EXPECT_NEAR(either.plane[3], -1.4, 0.01);  // most inliers
  prior.origin_above = true;
  const auto ground = ds3d::ransac_plane(p, prior);
  ASSERT_TRUE(ground.found);
  EXPECT_NEAR(ground.plane[3], 1.2, 0.01);
  EXPECT_GE(ground.inliers.size(), 1490U);
}

TEST(RansacPlane, ConfidenceOneRunsEveryIteration) {
  ds3d::test::Rng rng(51);
  const Points3f p = ds3d::test::plane_points(500, 1.0, 0.001, rng);
  EXPECT_EQ(ds3d::ransac_plane(p, {.max_iterations = 321, .confidence = 1.0}).iterations, 321U);
  EXPECT_LT(ds3d::ransac_plane(p, {.max_iterations = 321, .confidence = 0.99}).iterations, 321U);
}

TEST(RansacPlane, SameSeedSameResultForAnyThreadCount) {
  ds3d::test::Rng rng(61);
  // Large enough for the threaded path (smaller clouds always run on one thread).
  const auto s =
      ds3d::test::moving_object_scene(ds3d::kRansacParallelMinPoints + 20'000, 3000, 0.5, 3);
  RansacPlaneParams p;
  p.confidence = 0.99;
  p.seed = 7;
  const auto r1 = ds3d::ransac_plane(s.points, p);
  for (const int t : {2, 3, 0}) {
    p.num_threads = t;
    const auto rt = ds3d::ransac_plane(s.points, p);
    EXPECT_EQ(rt.plane, r1.plane);
    EXPECT_EQ(rt.inliers, r1.inliers);
    EXPECT_EQ(rt.iterations, r1.iterations);
  }
  p.seed = 8;
  p.num_threads = 1;
  const auto other = ds3d::ransac_plane(s.points, p);
  EXPECT_TRUE(other.found);
}

TEST(RansacPlane, RejectsBadParams) {
  const Points3f p = Points3f::Random(10, 3);
  EXPECT_THROW((void)ds3d::ransac_plane(p, {.distance_threshold = 0}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::ransac_plane(p, {.distance_threshold = -0.01}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::ransac_plane(p, {.max_iterations = 0}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::ransac_plane(p, {.confidence = 1.5}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::ransac_plane(p, {.confidence = std::nan("")}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::ransac_plane(p, {.max_angle_deg = 0}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::ransac_plane(p, {.num_threads = -1}), ds3d::InvalidArgument);
  try {
    (void)ds3d::ransac_plane(p, {.distance_threshold = -0.25});
    FAIL();
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("ds3d::ransac_plane: distance_threshold"),
              std::string::npos);
    EXPECT_NE(std::string(e.what()).find("-0.25"), std::string::npos);
  }
}

struct UserPoint {
  float x, y, z;
};
using UserCloud = std::vector<UserPoint>;

}  // namespace

template <>
struct ds3d::PointCloudTraits<UserCloud> {
  static std::size_t size(const UserCloud& c) { return c.size(); }
  static Eigen::Vector3f point(const UserCloud& c, std::size_t i) {
    return {c[i].x, c[i].y, c[i].z};
  }
};

namespace {

template <class C>
class RansacPlaneTyped : public ::testing::Test {};
using CloudTypes = ::testing::Types<Points3f, std::vector<Eigen::Vector3f>, UserCloud>;
TYPED_TEST_SUITE(RansacPlaneTyped, CloudTypes);

TYPED_TEST(RansacPlaneTyped, SameAsPoints3f) {
  ds3d::test::Rng rng(71);
  Points3f p(2000, 3);
  p.topRows(1200) = ds3d::test::plane_points(1200, 1.0, 0.003, rng);
  p.bottomRows(800) = ds3d::test::uniform_box(800, {-1, -1, -1}, {1, 1, 1}, rng);
  TypeParam c;
  if constexpr (std::is_same_v<TypeParam, Points3f>) {
    c = p;
  } else {
    for (Eigen::Index i = 0; i < p.rows(); ++i) c.push_back({p(i, 0), p(i, 1), p(i, 2)});
  }
  const auto ref = ds3d::ransac_plane(p);
  const auto r = ds3d::ransac_plane(c);
  EXPECT_EQ(r.plane, ref.plane);
  EXPECT_EQ(r.inliers, ref.inliers);
}

}  // namespace
