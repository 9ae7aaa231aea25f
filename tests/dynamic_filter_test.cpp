// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Tests of the box-gated HDBSCAN dynamic-keypoint filter on seeded synthetic keypoint scenes:
// a person-shaped slab in front of a wall, seen through its box, with occluders, border cuts,
// few keypoints, missing depth and detection misses.
#include "ds3d/dynamic_filter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "support/synthetic.hpp"

namespace {

using ds3d::DynamicFeatureFilter;
using ds3d::DynamicFilterParams;
using ds3d::ImageBox;
using ds3d::Keypoints3f;

// Keypoints of a scene, with the ground-truth "dynamic" flag of each.
struct Scene {
  std::vector<float> u, v, z;
  std::vector<std::uint8_t> truth;
  void add(float uu, float vv, float zz, bool dyn) {
    u.push_back(uu);
    v.push_back(vv);
    z.push_back(zz);
    truth.push_back(dyn ? 1 : 0);
  }
  [[nodiscard]] Keypoints3f matrix() const {
    Keypoints3f m(static_cast<Eigen::Index>(u.size()), 3);
    for (std::size_t i = 0; i < u.size(); ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      m(r, 0) = u[i];
      m(r, 1) = v[i];
      m(r, 2) = z[i];
    }
    return m;
  }
};

// A wall at depth `wall_z` covering the image, uniformly sampled (n_wall keypoints), and a person:
// the rectangle [u0,u1]×[v0,v1] at depth person_z (± 0.15 m body thickness), n_person keypoints.
Scene person_scene(ds3d::test::Rng& rng, int n_wall, float wall_z, int n_person, float u0, float v0,
                   float u1, float v1, float person_z) {
  Scene s;
  for (int i = 0; i < n_wall; ++i) {
    const auto u = static_cast<float>(rng.uniform(0, 639));
    const auto v = static_cast<float>(rng.uniform(0, 479));
    if (u >= u0 && u <= u1 && v >= v0 && v <= v1) continue;  // hidden behind the person
    s.add(u, v, wall_z + static_cast<float>(0.01 * rng.normal()), false);
  }
  for (int i = 0; i < n_person; ++i) {
    s.add(static_cast<float>(rng.uniform(u0, u1)), static_cast<float>(rng.uniform(v0, v1)),
          person_z + static_cast<float>(rng.uniform(-0.15, 0.15)), true);
  }
  return s;
}

struct Score {
  double precision = 0, recall = 0;
  int tp = 0, fp = 0, fn = 0;
};
Score score(const std::vector<std::uint8_t>& pred, const std::vector<std::uint8_t>& truth) {
  Score sc;
  for (std::size_t i = 0; i < pred.size(); ++i) {
    if (pred[i] != 0U && truth[i] != 0U) ++sc.tp;
    if (pred[i] != 0U && truth[i] == 0U) ++sc.fp;
    if (pred[i] == 0U && truth[i] != 0U) ++sc.fn;
  }
  sc.precision = sc.tp + sc.fp > 0 ? static_cast<double>(sc.tp) / (sc.tp + sc.fp) : 1.0;
  sc.recall = sc.tp + sc.fn > 0 ? static_cast<double>(sc.tp) / (sc.tp + sc.fn) : 1.0;
  return sc;
}

ImageBox box(float u0, float v0, float u1, float v1, float score = 0.9F) {
  ImageBox b;
  b.x_min = u0;
  b.y_min = v0;
  b.x_max = u1;
  b.y_max = v1;
  b.score = score;
  return b;
}

const ds3d::PinholeCamera kCam{};  // 640 × 480, f = 525

TEST(DynamicFilter, EmptyInputAndNoBoxes) {
  const Keypoints3f none(0, 3);
  auto r = ds3d::filter_dynamic_keypoints(none, {box(10, 10, 100, 100)}, kCam);
  EXPECT_TRUE(r.dynamic.empty());
  EXPECT_EQ(r.num_dynamic, 0);
  ds3d::test::Rng rng(1);
  const Scene s = person_scene(rng, 600, 3.0F, 200, 200, 100, 350, 460, 1.5F);
  r = ds3d::filter_dynamic_keypoints(s.matrix(), {}, kCam);
  ASSERT_EQ(r.dynamic.size(), s.u.size());
  EXPECT_EQ(r.num_dynamic, 0);
  EXPECT_TRUE(r.boxes.empty());
}

TEST(DynamicFilter, RejectsBadParamsAndBoxes) {
  EXPECT_THROW(DynamicFeatureFilter({.min_score = 1.5F}), ds3d::InvalidArgument);
  EXPECT_THROW(DynamicFeatureFilter({.min_cluster_size = 1}), ds3d::InvalidArgument);
  EXPECT_THROW(DynamicFeatureFilter({.depth_gap = 0.0F}), ds3d::InvalidArgument);
  EXPECT_THROW(DynamicFeatureFilter({.carry_frames = -1}), ds3d::InvalidArgument);
  const Keypoints3f kp = Keypoints3f::Zero(3, 3);
  EXPECT_THROW((void)ds3d::filter_dynamic_keypoints(kp, {box(100, 10, 50, 20)}, kCam),
               ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::filter_dynamic_keypoints(kp, {box(0, 0, 10, 10, 2.0F)}, kCam),
               ds3d::InvalidArgument);
  ImageBox nan_box = box(0, 0, 10, 10);
  nan_box.x_max = std::numeric_limits<float>::quiet_NaN();
  try {
    (void)ds3d::filter_dynamic_keypoints(kp, {box(0, 0, 5, 5), nan_box}, kCam);
    FAIL() << "expected InvalidArgument";
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("boxes[1]"), std::string::npos) << e.what();
  }
  ds3d::PinholeCamera bad = kCam;
  bad.fx = -1;
  EXPECT_THROW((void)ds3d::filter_dynamic_keypoints(kp, {}, bad), ds3d::InvalidArgument);
}

TEST(DynamicFilter, SeparatesPersonFromBackgroundInItsBox) {
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    ds3d::test::Rng rng(seed);
    const Scene s = person_scene(rng, 1200, 3.0F, 200, 220, 80, 360, 470, 1.6F);
    const auto r = ds3d::filter_dynamic_keypoints(s.matrix(), {box(220, 80, 360, 470)}, kCam);
    const Score sc = score(r.dynamic, s.truth);
    EXPECT_GE(sc.precision, 0.95) << "seed " << seed;
    EXPECT_GE(sc.recall, 0.95) << "seed " << seed;
    ASSERT_EQ(r.boxes.size(), 1U);
    EXPECT_FALSE(r.boxes[0].fallback);
    // The wall seen around the person inside the (grown) box must be kept: some exist.
    int wall_in_box = 0;
    for (std::size_t i = 0; i < s.u.size(); ++i) {
      if (s.truth[i] == 0U && r.boxes[0].box.contains(s.u[i], s.v[i])) ++wall_in_box;
    }
    EXPECT_GT(wall_in_box, 0);
    EXPECT_NEAR(r.boxes[0].z_front, 1.45F, 0.05F);
  }
}

TEST(DynamicFilter, BoxCoveringMostOfTheImage) {
  // The paper's case: a person close to the camera fills most of the frame; background only
  // around the edges and between the legs.
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    ds3d::test::Rng rng(seed);
    Scene s = person_scene(rng, 2000, 2.8F, 350, 60, 20, 560, 300, 0.9F);
    // Legs: two columns below the torso, wall visible between them.
    for (int i = 0; i < 120; ++i) {
      const bool left = i % 2 == 0;
      s.add(static_cast<float>(left ? rng.uniform(120, 240) : rng.uniform(380, 500)),
            static_cast<float>(rng.uniform(300, 479)),
            0.95F + static_cast<float>(rng.uniform(-0.1, 0.1)), true);
    }
    // Remove wall points that fall on the legs.
    Scene t;
    for (std::size_t i = 0; i < s.u.size(); ++i) {
      const bool on_leg =
          s.v[i] >= 300 && ((s.u[i] >= 120 && s.u[i] <= 240) || (s.u[i] >= 380 && s.u[i] <= 500));
      if (s.truth[i] == 0U && on_leg) continue;
      t.add(s.u[i], s.v[i], s.z[i], s.truth[i] != 0U);
    }
    const auto r = ds3d::filter_dynamic_keypoints(t.matrix(), {box(50, 10, 570, 479)}, kCam);
    const Score sc = score(r.dynamic, t.truth);
    EXPECT_GE(sc.precision, 0.95) << "seed " << seed;
    EXPECT_GE(sc.recall, 0.9) << "seed " << seed;
    // The wall between the legs is kept.
    int kept_between = 0;
    for (std::size_t i = 0; i < t.u.size(); ++i) {
      if (t.truth[i] == 0U && t.u[i] > 260 && t.u[i] < 360 && t.v[i] > 320 && r.dynamic[i] == 0U) {
        ++kept_between;
      }
    }
    EXPECT_GT(kept_between, 0) << "seed " << seed;
  }
}

TEST(DynamicFilter, OccludingFurnitureInFrontIsKept) {
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    ds3d::test::Rng rng(seed);
    // Person at 2.2 m, a table at 1.1 m hiding the lower third of the box.
    Scene s = person_scene(rng, 1500, 3.5F, 160, 260, 60, 380, 330, 2.2F);
    for (int i = 0; i < 90; ++i) {
      s.add(static_cast<float>(rng.uniform(200, 440)), static_cast<float>(rng.uniform(330, 420)),
            1.1F + static_cast<float>(rng.uniform(-0.05, 0.05)), false);
    }
    const auto r = ds3d::filter_dynamic_keypoints(s.matrix(), {box(260, 60, 380, 420)}, kCam);
    const Score sc = score(r.dynamic, s.truth);
    EXPECT_GE(sc.precision, 0.95) << "seed " << seed;
    EXPECT_GE(sc.recall, 0.9) << "seed " << seed;
    for (std::size_t i = 0; i < s.u.size(); ++i) {
      if (std::abs(s.z[i] - 1.1F) < 0.06F) {
        EXPECT_EQ(r.dynamic[i], 0) << "table point " << i;
      }
    }
  }
}

TEST(DynamicFilter, PartialViewAtTheImageBorder) {
  ds3d::test::Rng rng(7);
  // The person enters from the right: its box extends beyond the image and is clipped.
  const Scene s = person_scene(rng, 1200, 3.0F, 120, 560, 60, 639, 470, 1.4F);
  const auto r = ds3d::filter_dynamic_keypoints(s.matrix(), {box(560, 60, 720, 470)}, kCam);
  const Score sc = score(r.dynamic, s.truth);
  EXPECT_GE(sc.precision, 0.95);
  EXPECT_GE(sc.recall, 0.95);
  ASSERT_EQ(r.boxes.size(), 1U);
  EXPECT_LE(r.boxes[0].box.x_max, 639.5F);
}

TEST(DynamicFilter, TooFewKeypointsUseTheDepthGapFallback) {
  Scene s;
  // 5 on the person at ~1.5 m, 4 on the wall at 3 m, one flying pixel at 0.5 m.
  const float pu[5] = {300, 310, 305, 295, 315};
  for (int i = 0; i < 5; ++i) s.add(pu[i], 200.0F + 20.0F * static_cast<float>(i), 1.5F, true);
  for (int i = 0; i < 4; ++i) s.add(330.0F, 150.0F + 40.0F * static_cast<float>(i), 3.0F, false);
  s.add(320.0F, 300.0F, 0.5F, false);
  const auto r = ds3d::filter_dynamic_keypoints(s.matrix(), {box(280, 140, 340, 320)}, kCam);
  ASSERT_EQ(r.boxes.size(), 1U);
  EXPECT_TRUE(r.boxes[0].fallback);
  EXPECT_EQ(r.dynamic, s.truth);
}

TEST(DynamicFilter, KeypointsWithoutDepthAndNonFiniteOnes) {
  ds3d::test::Rng rng(3);
  Scene s = person_scene(rng, 1000, 3.0F, 200, 200, 100, 330, 460, 1.5F);
  const std::size_t first_extra = s.u.size();
  s.add(260, 300, 0.0F, true);  // no depth, on the person
  s.add(205, 110, std::numeric_limits<float>::quiet_NaN(), true);
  s.add(600, 50, 0.0F, false);                                       // no depth, far from any box
  s.add(std::numeric_limits<float>::quiet_NaN(), 300, 1.5F, false);  // unusable pixel
  const auto r = ds3d::filter_dynamic_keypoints(s.matrix(), {box(200, 100, 330, 460)}, kCam);
  EXPECT_EQ(r.num_non_finite, 1U);
  EXPECT_EQ(r.dynamic[first_extra], 1);
  EXPECT_EQ(r.dynamic[first_extra + 1], 1);
  EXPECT_EQ(r.dynamic[first_extra + 2], 0);
  EXPECT_EQ(r.dynamic[first_extra + 3], 0);
  int count = 0;
  for (const auto d : r.dynamic) count += d;
  EXPECT_EQ(count, r.num_dynamic);
}

TEST(DynamicFilter, LowScoreBoxesAreIgnored) {
  ds3d::test::Rng rng(4);
  const Scene s = person_scene(rng, 800, 3.0F, 150, 200, 100, 330, 460, 1.5F);
  const auto r = ds3d::filter_dynamic_keypoints(s.matrix(), {box(200, 100, 330, 460, 0.1F)}, kCam);
  EXPECT_EQ(r.num_dynamic, 0);
  EXPECT_EQ(r.num_ignored_boxes, 1U);
}

TEST(DynamicFilter, CarriesRegionsOverDetectionMisses) {
  DynamicFeatureFilter filt({.carry_frames = 1});
  ds3d::test::Rng rng(5);
  const Scene s0 = person_scene(rng, 1000, 3.0F, 200, 200, 100, 330, 460, 1.5F);
  auto r = filt.filter(s0.matrix(), {box(200, 100, 330, 460)}, kCam);
  EXPECT_GE(score(r.dynamic, s0.truth).recall, 0.95);
  ASSERT_EQ(filt.carried_regions().size(), 1U);
  // Frame 1: the detector misses; the person moved 10 px right.
  const Scene s1 = person_scene(rng, 1000, 3.0F, 200, 210, 100, 340, 460, 1.5F);
  r = filt.filter(s1.matrix(), {}, kCam);
  ASSERT_EQ(r.boxes.size(), 1U);
  EXPECT_TRUE(r.boxes[0].carried);
  const Score sc = score(r.dynamic, s1.truth);
  EXPECT_GE(sc.precision, 0.95);
  EXPECT_GE(sc.recall, 0.9);
  // Frame 2: still no detection; carry_frames = 1 has run out.
  r = filt.filter(s1.matrix(), {}, kCam);
  EXPECT_EQ(r.num_dynamic, 0);
  EXPECT_TRUE(filt.carried_regions().empty());
}

TEST(DynamicFilter, ProjectedThreeDBoxGatesDepth) {
  // A 0.6 × 1.7 × 0.4 m box centred 2 m ahead (camera frame: y down).
  Eigen::Matrix<float, 8, 3> c;
  int k = 0;
  for (const float x : {-0.3F, 0.3F}) {
    for (const float y : {-0.85F, 0.85F}) {
      for (const float z : {1.8F, 2.2F}) c.row(k++) << x, y, z;
    }
  }
  const auto pb = ds3d::project_box(c, kCam);
  ASSERT_TRUE(pb.has_value());
  EXPECT_NEAR(pb->x_min, 319.5F - 0.3F * 525.0F / 1.8F, 1e-3F);
  EXPECT_NEAR(pb->x_max, 319.5F + 0.3F * 525.0F / 1.8F, 1e-3F);
  EXPECT_NEAR(pb->y_min, -0.5F, 1e-6F);  // clipped at the top (0.85·525/1.8 > 239.5)
  EXPECT_FLOAT_EQ(pb->z_min, 1.8F);
  EXPECT_FLOAT_EQ(pb->z_max, 2.2F);
  // Entirely behind the camera: nothing; straddling the near plane: clipped, still a box.
  Eigen::Matrix<float, 8, 3> behind = c;
  behind.col(2).array() -= 3.0F;
  EXPECT_FALSE(ds3d::project_box(behind, kCam).has_value());
  Eigen::Matrix<float, 8, 3> straddle = c;
  straddle.col(2).array() -= 2.0F;
  const auto ps = ds3d::project_box(straddle, kCam);
  ASSERT_TRUE(ps.has_value());
  EXPECT_NEAR(ps->z_min, 0.05F, 1e-6F);
  EXPECT_TRUE(std::isfinite(ps->x_min) && std::isfinite(ps->x_max) && std::isfinite(ps->y_min) &&
              std::isfinite(ps->y_max));
  EXPECT_LE(ps->x_min, ps->x_max);
  // The projected box's depth range keeps the wall out, even when the wall is close behind.
  ds3d::test::Rng rng(11);
  const Scene s = person_scene(rng, 1500, 2.6F, 150, pb->x_min + 5, 10, pb->x_max - 5, 470, 2.0F);
  const auto r = ds3d::filter_dynamic_keypoints(s.matrix(), {*pb}, kCam);
  const Score sc = score(r.dynamic, s.truth);
  EXPECT_GE(sc.precision, 0.95);
  EXPECT_GE(sc.recall, 0.95);
}

TEST(DynamicFilter, SameResultWhenRepeated) {
  ds3d::test::Rng rng(9);
  const Scene s = person_scene(rng, 1500, 3.0F, 300, 150, 50, 400, 470, 1.2F);
  const auto a = ds3d::filter_dynamic_keypoints(s.matrix(), {box(150, 50, 400, 470)}, kCam);
  const auto b = ds3d::filter_dynamic_keypoints(s.matrix(), {box(150, 50, 400, 470)}, kCam);
  EXPECT_EQ(a.dynamic, b.dynamic);
}

}  // namespace
