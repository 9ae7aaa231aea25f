// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Tests of the box-gated HDBSCAN dynamic-keypoint filter on seeded synthetic keypoint scenes:
// a person-shaped slab in front of a wall, seen through its box, with occluders, border cuts,
// few keypoints, missing depth and detection misses.
#include "ds3d/dynamic/dynamic_filter.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
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

// Eight corners of an oriented box (any order) → SolidBox: axes, half sizes and containment
// match the box the corners were made from; a non-cuboid is refused.
TEST(SolidBox, FromCornersRecoversTheOrientedBox) {
  ds3d::test::Rng rng(21);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3f axis =
        Eigen::Vector3f(static_cast<float>(rng.normal()), static_cast<float>(rng.normal()),
                        static_cast<float>(rng.normal()))
            .normalized();
    const Eigen::Matrix3f R =
        Eigen::AngleAxisf(static_cast<float>(rng.uniform(-3.1, 3.1)), axis).toRotationMatrix();
    const Eigen::Vector3f half(static_cast<float>(rng.uniform(0.1, 1.0)),
                               static_cast<float>(rng.uniform(0.1, 1.0)),
                               static_cast<float>(rng.uniform(0.1, 1.0)));
    const Eigen::Vector3f centre(static_cast<float>(rng.uniform(-1, 1)),
                                 static_cast<float>(rng.uniform(-1, 1)),
                                 static_cast<float>(rng.uniform(1, 4)));
    std::vector<Eigen::Vector3f> pts;
    for (const float a : {-1.0F, 1.0F}) {
      for (const float b : {-1.0F, 1.0F}) {
        for (const float c : {-1.0F, 1.0F}) {
          pts.emplace_back(centre + R * Eigen::Vector3f(a * half.x(), b * half.y(), c * half.z()));
        }
      }
    }
    // A shuffled order (the rotation by trial keeps it deterministic).
    std::rotate(pts.begin(), pts.begin() + trial % 8, pts.end());
    std::swap(pts[1], pts[6]);
    Eigen::Matrix<float, 8, 3> corners;
    for (int k = 0; k < 8; ++k) corners.row(k) = pts[static_cast<std::size_t>(k)].transpose();
    const auto solid = ds3d::solid_from_corners(corners, 0.0F);
    ASSERT_TRUE(solid.has_value()) << "trial " << trial;
    EXPECT_LT((solid->centre - centre).norm(), 1e-4F);
    EXPECT_LT((solid->axes * solid->axes.transpose() - Eigen::Matrix3f::Identity()).norm(), 1e-4F);
    std::vector<float> got(solid->half.data(), solid->half.data() + 3);
    std::vector<float> want(half.data(), half.data() + 3);
    std::sort(got.begin(), got.end());
    std::sort(want.begin(), want.end());
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(got[k], want[k], 1e-4F);
    for (int q = 0; q < 200; ++q) {
      const Eigen::Vector3f local(static_cast<float>(rng.uniform(-1.3, 1.3)) * half.x(),
                                  static_cast<float>(rng.uniform(-1.3, 1.3)) * half.y(),
                                  static_cast<float>(rng.uniform(-1.3, 1.3)) * half.z());
      const bool inside = (local.cwiseAbs().array() <= half.array() * 0.999F).all();
      const bool outside = (local.cwiseAbs().array() > half.array() * 1.001F).any();
      const Eigen::Vector3f p = centre + R * local;
      const bool got_in = solid->contains(p, Eigen::Vector3f::UnitZ(), 0.0F);
      if (inside) {
        EXPECT_TRUE(got_in);
      }
      if (outside) {
        EXPECT_FALSE(got_in);
      }
    }
    Eigen::Matrix<float, 8, 3> bent = corners;
    bent.row(3) += Eigen::Vector3f(0.05F, 0.0F, 0.0F).transpose();
    EXPECT_FALSE(ds3d::solid_from_corners(bent, 0.0F).has_value());
  }
  EXPECT_FALSE(ds3d::solid_from_corners(Eigen::Matrix<float, 8, 3>::Zero(), 0.0F).has_value());
  Eigen::Matrix<float, 8, 3> nan = Eigen::Matrix<float, 8, 3>::Ones();
  nan(2, 1) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(ds3d::solid_from_corners(nan, 0.0F).has_value());
  EXPECT_THROW((void)ds3d::solid_from_corners(nan, -1.0F), ds3d::InvalidArgument);
}

// Camera 1.2 m above a textured floor (camera frame: y down, floor y = 1.2 m) and a wall 5 m
// ahead; a person 0.5 m wide and 1.7 m tall stands on the floor 2.5 m ahead, inside a loose box
// that reaches down to the floor around the feet. Floor keypoints there are continuous in depth
// with the feet, so without the plane the foreground takes them in; with it they stay static.
struct FloorScene {
  Scene s;
  std::vector<std::uint8_t> on_floor;
  ImageBox loose;
};
FloorScene person_on_floor(ds3d::test::Rng& rng) {
  FloorScene fs;
  const float f = 525.0F, cx = 319.5F, cy = 239.5F, h = 1.2F, zp = 2.5F;
  const auto add = [&](float x, float y, float z, bool dyn, bool floor) {
    const float u = f * x / z + cx;
    const float v = f * y / z + cy;
    if (u < 0 || u > 639 || v < 0 || v > 479) return;
    fs.s.add(u, v, z, dyn);
    fs.on_floor.push_back(floor ? 1 : 0);
  };
  for (int i = 0; i < 1500; ++i) {  // floor, 1-5 m ahead, 2 mm relief
    const auto x = static_cast<float>(rng.uniform(-2.0, 2.0));
    const auto z = static_cast<float>(rng.uniform(1.0, 5.0));
    add(x, h + static_cast<float>(0.002 * rng.normal()), z, false, true);
  }
  for (int i = 0; i < 800; ++i) {  // wall
    add(static_cast<float>(rng.uniform(-2.5, 2.5)), static_cast<float>(rng.uniform(-1.5, h)),
        5.0F + static_cast<float>(0.01 * rng.normal()), false, false);
  }
  for (int i = 0; i < 300; ++i) {  // the person, feet on the floor
    add(static_cast<float>(rng.uniform(-0.25, 0.25)), static_cast<float>(rng.uniform(h - 1.7, h)),
        zp + static_cast<float>(rng.uniform(-0.15, 0.15)), true, false);
  }
  // A loose detection: 0.4 m wider per side and 0.3 m below the feet (at the person's depth).
  fs.loose = box(cx + f * -0.65F / zp, cy + f * (h - 1.8F) / zp, cx + f * 0.65F / zp,
                 cy + f * (h + 0.3F) / zp);
  return fs;
}

TEST(DynamicFilter, FloorUnderAStandingPersonStaysStatic) {
  ds3d::test::Rng rng(31);
  const FloorScene fs = person_on_floor(rng);
  const Eigen::Vector4f floor(0.0F, -1.0F, 0.0F, 1.2F);  // -y + 1.2 = 0
  const auto count_floor = [&](const std::vector<std::uint8_t>& dyn) {
    int k = 0;
    for (std::size_t i = 0; i < dyn.size(); ++i) k += (dyn[i] != 0U && fs.on_floor[i] != 0U);
    return k;
  };
  const auto without = ds3d::filter_dynamic_keypoints(fs.s.matrix(), {fs.loose}, kCam);
  const auto with = ds3d::filter_dynamic_keypoints(fs.s.matrix(), {fs.loose}, kCam, {}, floor);
  const Score a = score(without.dynamic, fs.s.truth);
  const Score b = score(with.dynamic, fs.s.truth);
  // The scene reproduces the failure: floor around the feet is taken in without the plane.
  EXPECT_GT(count_floor(without.dynamic), 20) << "precision " << a.precision;
  EXPECT_EQ(count_floor(with.dynamic), 0);
  EXPECT_GT(with.num_on_support, 20);
  EXPECT_GE(b.precision, 0.95);
  EXPECT_GE(b.recall, 0.9);
  EXPECT_GT(b.precision, a.precision);
  // A plane given with any scale of (n, d) is the same plane; a zero normal is refused.
  const auto scaled = ds3d::filter_dynamic_keypoints(fs.s.matrix(), {fs.loose}, kCam, {},
                                                     Eigen::Vector4f(floor * 3));
  EXPECT_EQ(scaled.dynamic, with.dynamic);
  EXPECT_THROW((void)ds3d::filter_dynamic_keypoints(fs.s.matrix(), {fs.loose}, kCam, {},
                                                    Eigen::Vector4f(0, 0, 0, 1)),
               ds3d::InvalidArgument);
  DynamicFilterParams bad;
  bad.support_margin = -0.01F;
  EXPECT_THROW(DynamicFeatureFilter{bad}, ds3d::InvalidArgument);
}

// A keypoint inside the projected rectangle and the depth range of a 3-D box, but beside the
// box in 3-D (a cupboard behind and beside the person, continuous in depth with them), is static
// when the box is known as a solid; without the solid it joins the foreground.
TEST(DynamicFilter, SolidBoxKeepsWhatLiesBesideTheObjectStatic) {
  Eigen::Matrix<float, 8, 3> c;  // x ±0.3 m, y ±0.85 m, z 2-3 m
  int k = 0;
  for (const float x : {-0.3F, 0.3F}) {
    for (const float y : {-0.85F, 0.85F}) {
      for (const float z : {2.0F, 3.0F}) c.row(k++) << x, y, z;
    }
  }
  const auto pb = ds3d::project_box(c, kCam);
  ASSERT_TRUE(pb.has_value());
  ds3d::test::Rng rng(41);
  Scene s;
  std::vector<std::uint8_t> cupboard;
  const auto add = [&](float x, float y, float z, bool dyn, bool cup) {
    s.add(525.0F * x / z + 319.5F, 525.0F * y / z + 239.5F, z, dyn);
    cupboard.push_back(cup ? 1 : 0);
  };
  for (int i = 0; i < 250; ++i) {  // the person, inside the box
    add(static_cast<float>(rng.uniform(-0.25, 0.25)), static_cast<float>(rng.uniform(-0.8, 0.8)),
        static_cast<float>(rng.uniform(2.3, 2.6)), true, false);
  }
  for (int i = 0; i < 120; ++i) {  // the cupboard's side, 0.07-0.1 m beside the box, z 2.7-2.95
    const auto z = static_cast<float>(rng.uniform(2.7, 2.95));
    add(static_cast<float>(rng.uniform(0.37, 0.40)), static_cast<float>(rng.uniform(-0.8, 0.8)), z,
        false, true);
  }
  for (int i = 0; i < 1000; ++i) {  // wall behind, out of the depth range
    add(static_cast<float>(rng.uniform(-2.0, 2.0)), static_cast<float>(rng.uniform(-1.5, 1.5)),
        4.0F + static_cast<float>(0.01 * rng.normal()), false, false);
  }
  int in_rect = 0;
  for (std::size_t i = 0; i < s.u.size(); ++i) {
    in_rect += (cupboard[i] != 0U && pb->contains(s.u[i], s.v[i])) ? 1 : 0;
  }
  ASSERT_GT(in_rect, 60);  // the cupboard is in the rectangle and the depth range
  const auto count_cup = [&](const std::vector<std::uint8_t>& dyn) {
    int n = 0;
    for (std::size_t i = 0; i < dyn.size(); ++i) n += (dyn[i] != 0U && cupboard[i] != 0U);
    return n;
  };
  const auto rect_only = ds3d::filter_dynamic_keypoints(s.matrix(), {*pb}, kCam);
  ImageBox solid = *pb;
  solid.solid = ds3d::solid_from_corners(c, 0.05F);
  ASSERT_TRUE(solid.solid.has_value());
  const auto gated = ds3d::filter_dynamic_keypoints(s.matrix(), {solid}, kCam);
  EXPECT_GT(count_cup(rect_only.dynamic), in_rect / 2);
  EXPECT_EQ(count_cup(gated.dynamic), 0);
  EXPECT_GE(gated.num_outside_solid, in_rect);
  const Score sc = score(gated.dynamic, s.truth);
  EXPECT_GE(sc.precision, 0.95);
  EXPECT_GE(sc.recall, 0.95);
  // The region carried over a detection miss keeps the solid, grown by carry_motion.
  DynamicFeatureFilter carrying;  // carry_frames 1
  (void)carrying.filter(s.matrix(), {solid}, kCam);
  ASSERT_EQ(carrying.carried_regions().size(), 1U);
  ASSERT_TRUE(carrying.carried_regions()[0].solid.has_value());
  const auto missed = carrying.filter(s.matrix(), {}, kCam);
  ASSERT_EQ(missed.boxes.size(), 1U);
  ASSERT_TRUE(missed.boxes[0].carried && missed.boxes[0].box.solid.has_value());
  EXPECT_FLOAT_EQ(missed.boxes[0].box.solid->margin, 0.05F + carrying.params().carry_motion);
  // A malformed solid is refused, naming the box.
  ImageBox bad = solid;
  bad.solid->half.x() = -1.0F;
  try {
    (void)ds3d::filter_dynamic_keypoints(s.matrix(), {solid, bad}, kCam);
    ADD_FAILURE() << "no exception";
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("boxes[1].solid"), std::string::npos) << e.what();
  }
}

TEST(DynamicFilter, SameResultWhenRepeated) {
  ds3d::test::Rng rng(9);
  const Scene s = person_scene(rng, 1500, 3.0F, 300, 150, 50, 400, 470, 1.2F);
  const auto a = ds3d::filter_dynamic_keypoints(s.matrix(), {box(150, 50, 400, 470)}, kCam);
  const auto b = ds3d::filter_dynamic_keypoints(s.matrix(), {box(150, 50, 400, 470)}, kCam);
  EXPECT_EQ(a.dynamic, b.dynamic);
}

}  // namespace
