// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d::remove_radius_outliers against the golden fixtures, brute force and edge cases.
#include "ds3d/preprocess/radius_outlier.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <vector>

#include "support/preprocess_fixtures.hpp"
#include "support/synthetic.hpp"

namespace {

using ds3d::Points3f;
using ds3d::RadiusOutlierParams;

/// Definition from the fixture README, O(n^2), in double.
std::vector<std::uint32_t> brute_force(const Points3f& p, double radius, std::uint32_t k) {
  std::vector<std::uint32_t> kept;
  const double r2 = radius * radius;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    if (!p.row(i).allFinite()) continue;
    std::uint32_t count = 0;
    for (Eigen::Index j = 0; j < p.rows(); ++j) {
      if (j == i || !p.row(j).allFinite()) continue;
      const double d = (p.row(i).cast<double>() - p.row(j).cast<double>()).squaredNorm();
      count += d <= r2 ? 1U : 0U;
    }
    if (count >= k) kept.push_back(static_cast<std::uint32_t>(i));
  }
  return kept;
}

TEST(RadiusOutlier, MatchesEveryGoldenFixture) {
  int checked = 0;
  for (const auto& root : ds3d::test::preprocess_fixture_roots()) {
    for (const auto& dir : ds3d::test::preprocess_cases(root)) {
      const auto meta = ds3d::test::read_json(dir / "case.json");
      if (!meta.at("outputs").contains("radius")) continue;
      const Points3f pts = ds3d::test::read_points_bin(dir / "input.bin");
      for (const auto& out : meta.at("outputs").at("radius").as_array()) {
        const auto file = dir / out.at("kept_file").as_string();
        if (!std::filesystem::exists(file)) continue;
        const auto golden = ds3d::test::read_indices(file);
        ASSERT_EQ(golden.size(), static_cast<std::size_t>(out.at("n_kept").as_int()));
        for (const auto search : {ds3d::RadiusSearch::kGrid, ds3d::RadiusSearch::kKdTree}) {
          for (const int threads : {1, 3}) {
            RadiusOutlierParams p;
            p.radius = out.at("radius").as_number();
            p.min_neighbors = static_cast<std::uint32_t>(out.at("k").as_int());
            p.num_threads = threads;
            p.search = search;
            const auto r = ds3d::remove_radius_outliers(pts, p);
            EXPECT_EQ(r.kept, golden) << file.string() << " threads " << threads << " search "
                                      << static_cast<int>(search);
          }
        }
        ++checked;
      }
    }
  }
  EXPECT_GE(checked, 7);  // in-repo copy: 7 kept files
}

TEST(RadiusOutlier, MatchesBruteForce) {
  ds3d::test::Rng rng(21);
  Points3f p(3000, 3);
  p.topRows(2000) = ds3d::test::plane_points(2000, 1.0, 0.02, rng);
  p.bottomRows(1000) = ds3d::test::uniform_box(1000, {-1.5, -1.5, -1}, {1.5, 1.5, 1}, rng);
  for (Eigen::Index i = 0; i < 30; ++i) p.row(2500 + i) = p.row(2400);  // exact duplicates
  for (const auto& [radius, k] : {std::pair{0.05, 3U}, {0.1, 8U}, {0.2, 1U}, {0.03, 30U}}) {
    const auto r = ds3d::remove_radius_outliers(p, {.radius = radius, .min_neighbors = k});
    EXPECT_EQ(r.kept, brute_force(p, radius, k)) << "R " << radius << " k " << k;
    const auto t = ds3d::remove_radius_outliers(
        p, {.radius = radius, .min_neighbors = k, .search = ds3d::RadiusSearch::kKdTree});
    EXPECT_EQ(t.kept, r.kept) << "kd-tree, R " << radius << " k " << k;
  }
}

TEST(RadiusOutlier, KdTreeMatchesGridOnRandomClouds) {
  ds3d::test::Rng rng(77);
  for (int trial = 0; trial < 6; ++trial) {
    Points3f p(4000, 3);
    p.topRows(2500) = ds3d::test::plane_points(2500, 2.0, 0.03, rng);
    p.bottomRows(1500) = ds3d::test::uniform_box(1500, {-2, -2, -1}, {2, 2, 1}, rng);
    p.row(7) = p.row(8);                                            // a duplicate
    p(11, 0) = std::numeric_limits<float>::quiet_NaN();             // a non-finite point
    p.row(12) = p.row(13) + Eigen::RowVector3f(0.05F, 0.0F, 0.0F);  // near a tie
    p.array() += static_cast<float>(trial) * 3.7F;                  // away from the origin
    const double radius = 0.03 + 0.02 * trial;
    for (const std::uint32_t k : {1U, 4U, 16U}) {
      for (const int threads : {1, 2}) {
        const auto g = ds3d::remove_radius_outliers(
            p, {.radius = radius, .min_neighbors = k, .num_threads = threads});
        const auto t = ds3d::remove_radius_outliers(p, {.radius = radius,
                                                        .min_neighbors = k,
                                                        .num_threads = threads,
                                                        .search = ds3d::RadiusSearch::kKdTree});
        EXPECT_EQ(t.kept, g.kept) << "trial " << trial << " k " << k;
        EXPECT_EQ(t.num_non_finite, g.num_non_finite);
      }
    }
  }
}

TEST(RadiusOutlier, EmptyAndOnePoint) {
  const Points3f none(0, 3);
  EXPECT_TRUE(ds3d::remove_radius_outliers(none).kept.empty());
  Points3f one(1, 3);
  one << 1, 2, 3;
  EXPECT_TRUE(ds3d::remove_radius_outliers(one, {.radius = 1, .min_neighbors = 1}).kept.empty());
  // k = 0: every finite point is kept, even alone.
  EXPECT_EQ(ds3d::remove_radius_outliers(one, {.radius = 1, .min_neighbors = 0}).kept,
            std::vector<std::uint32_t>{0});
}

TEST(RadiusOutlier, DuplicatesAreNeighboursAndTiesAreKept) {
  Points3f p(4, 3);
  p << 0, 0, 0, 0, 0, 0, 0.5F, 0, 0, 5, 5, 5;
  // Point 0 and 1 coincide: each has one neighbour at distance 0.
  EXPECT_EQ(ds3d::remove_radius_outliers(p, {.radius = 0.1, .min_neighbors = 1}).kept,
            (std::vector<std::uint32_t>{0, 1}));
  // Distance exactly 0.5 (representable): <= R keeps it.
  EXPECT_EQ(ds3d::remove_radius_outliers(p, {.radius = 0.5, .min_neighbors = 2}).kept,
            (std::vector<std::uint32_t>{0, 1, 2}));
  // All points in one cell.
  const Points3f same = Points3f::Constant(50, 3, 0.25F);
  EXPECT_EQ(ds3d::remove_radius_outliers(same, {.radius = 0.1, .min_neighbors = 49}).kept.size(),
            50U);
  EXPECT_TRUE(
      ds3d::remove_radius_outliers(same, {.radius = 0.1, .min_neighbors = 50}).kept.empty());
}

TEST(RadiusOutlier, NonFiniteInput) {
  Points3f p(5, 3);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  p << 0, 0, 0, nan, 0, 0, 0.01F, 0, 0, 0, std::numeric_limits<float>::infinity(), 0, 0, 0.01F, 0;
  const auto r = ds3d::remove_radius_outliers(p, {.radius = 0.05, .min_neighbors = 2});
  EXPECT_EQ(r.kept, (std::vector<std::uint32_t>{0, 2, 4}));
  EXPECT_EQ(r.num_non_finite, 2U);
  EXPECT_THROW((void)ds3d::remove_radius_outliers(p, {.on_non_finite = ds3d::NonFinite::kThrow}),
               ds3d::InvalidArgument);
}

TEST(RadiusOutlier, SameResultForAnyThreadCount) {
  ds3d::test::Rng rng(8);
  const Points3f p = ds3d::test::uniform_box(40'000, {-1, -1, -1}, {1, 1, 1}, rng);
  const auto r1 = ds3d::remove_radius_outliers(p, {.radius = 0.06, .min_neighbors = 5});
  EXPECT_GT(r1.kept.size(), 1000U);
  EXPECT_LT(r1.kept.size(), 39'000U);
  for (const int t : {2, 5, 0}) {
    EXPECT_EQ(
        ds3d::remove_radius_outliers(p, {.radius = 0.06, .min_neighbors = 5, .num_threads = t})
            .kept,
        r1.kept);
  }
}

TEST(RadiusOutlier, RejectsBadParams) {
  const Points3f p = Points3f::Zero(3, 3);
  EXPECT_THROW((void)ds3d::remove_radius_outliers(p, {.radius = 0}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::remove_radius_outliers(p, {.radius = -1}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::remove_radius_outliers(p, {.radius = std::nan("")}),
               ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::remove_radius_outliers(p, {.num_threads = -2}), ds3d::InvalidArgument);
  try {
    (void)ds3d::remove_radius_outliers(p, {.radius = -0.5});
    FAIL();
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("ds3d::remove_radius_outliers: radius"),
              std::string::npos);
    EXPECT_NE(std::string(e.what()).find("-0.5"), std::string::npos);
  }
  // A grid too fine for the extent.
  Points3f far(2, 3);
  far << 0, 0, 0, 1e30F, 0, 0;
  EXPECT_THROW((void)ds3d::remove_radius_outliers(far, {.radius = 1e-3}), ds3d::InvalidArgument);
}

struct UserPoint {
  float p[3];
};
using UserCloud = std::vector<UserPoint>;

}  // namespace

template <>
struct ds3d::PointCloudTraits<UserCloud> {
  static std::size_t size(const UserCloud& c) { return c.size(); }
  static Eigen::Vector3f point(const UserCloud& c, std::size_t i) {
    return {c[i].p[0], c[i].p[1], c[i].p[2]};
  }
};

namespace {

template <class C>
C convert(const Points3f& p) {
  C v;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    if constexpr (std::is_same_v<C, UserCloud>) {
      v.push_back({{p(i, 0), p(i, 1), p(i, 2)}});
    } else {
      v.emplace_back(p.row(i).transpose());
    }
  }
  return v;
}
template <>
Points3f convert(const Points3f& p) {
  return p;
}

template <class C>
class RadiusOutlierTyped : public ::testing::Test {};
using CloudTypes = ::testing::Types<Points3f, std::vector<Eigen::Vector3f>, UserCloud>;
TYPED_TEST_SUITE(RadiusOutlierTyped, CloudTypes);

TYPED_TEST(RadiusOutlierTyped, SameAsBruteForce) {
  ds3d::test::Rng rng(9);
  const Points3f p = ds3d::test::uniform_box(2000, {0, 0, 0}, {1, 1, 1}, rng);
  const auto r =
      ds3d::remove_radius_outliers(convert<TypeParam>(p), {.radius = 0.08, .min_neighbors = 4});
  EXPECT_EQ(r.kept, brute_force(p, 0.08, 4));
  const auto t = ds3d::remove_radius_outliers(
      convert<TypeParam>(p),
      {.radius = 0.08, .min_neighbors = 4, .search = ds3d::RadiusSearch::kKdTree});
  EXPECT_EQ(t.kept, r.kept);
}

}  // namespace
