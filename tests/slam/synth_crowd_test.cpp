// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Crowd stress scenarios of the synthetic generator: people in view, close coverage, carried
// objects in mask and box, handheld camera, motion blur, determinism, noisy detections.
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "ds3d/dynamic/detections.hpp"
#include "ds3d/slam/synth.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;
using ds3d::synth::Scenario;
using ds3d::synth::SyntheticScene;
using ds3d::synth::SynthOptions;

constexpr Scenario kCrowd[] = {Scenario::kCrowdCross, Scenario::kCrowdBoard, Scenario::kCrowdStart,
                               Scenario::kCrowdHandheld};
constexpr std::size_t kPeople[] = {4, 3, 5, 4};

// Half the default resolution: the same views at a quarter of the rendering time.
ds3d::PinholeCamera half_vga() {
  ds3d::PinholeCamera c;
  c.fx = c.fy = 262.5;
  c.cx = 159.5;
  c.cy = 119.5;
  c.width = 320;
  c.height = 240;
  return c;
}

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

TEST(SynthCrowd, NamesAndHumanLimits) {
  for (const char* n : {"crowd_cross", "crowd_board", "crowd_start", "crowd_handheld"}) {
    EXPECT_EQ(ds3d::synth::scenario_name(ds3d::synth::parse_scenario(n)), n);
    EXPECT_TRUE(ds3d::synth::is_crowd(ds3d::synth::parse_scenario(n)));
  }
  EXPECT_FALSE(ds3d::synth::is_crowd(Scenario::kWalkingXyz));
  EXPECT_THROW(SyntheticScene({.scenario = Scenario::kCrowdCross, .num_humans = 2}),
               ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.scenario = Scenario::kCrowdCross, .num_humans = 7}),
               ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.num_humans = 6}), ds3d::InvalidArgument);  // walking_xyz: 0-4
  EXPECT_EQ(SyntheticScene({.scenario = Scenario::kCrowdBoard, .num_frames = 1, .num_humans = 6})
                .render(0)
                .boxes.size(),
            6U);
  EXPECT_THROW(SyntheticScene({.detection_miss = 0.9}), ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.detection_false = -0.1}), ds3d::InvalidArgument);
}

// Per scenario: everyone in view at frame 0, the closest person covering 30-70 % of the image
// in some frame, carried objects in the mask and inside their person's box.
TEST(SynthCrowd, PeopleCloseCarryingAndInView) {
  const ds3d::PinholeCamera cam = half_vga();
  const double area = cam.width * cam.height;
  for (std::size_t s = 0; s < 4; ++s) {
    SCOPED_TRACE(ds3d::synth::scenario_name(kCrowd[s]));
    const SyntheticScene scene(
        {.scenario = kCrowd[s], .num_frames = 150, .seed = 1, .camera = cam});
    const auto f0 = scene.render(0);
    ASSERT_EQ(f0.boxes.size(), kPeople[s]);
    for (const auto& b : f0.boxes) EXPECT_GT(b.visible_pixels, 0) << "person " << b.id;
    if (kCrowd[s] == Scenario::kCrowdStart) {
      const double cover = cv::countNonZero(f0.dynamic_mask) / area;
      EXPECT_GE(cover, 0.3);
      EXPECT_LE(cover, 0.7);
    }
    bool close = false;
    std::vector<int> carried_seen(kPeople[s], 0);
    for (std::size_t i = 0; i < scene.size(); i += 3) {
      const auto f = scene.render(i);
      int closest = 0;
      for (const auto& b : f.boxes) closest = std::max(closest, b.visible_pixels);
      close = close || (closest >= 0.3 * area && closest <= 0.7 * area);
      // Carried pixels: a human id with part 0; dynamic, and inside the human's (grown) box.
      for (int y = 0; y < cam.height; y += 2) {
        for (int x = 0; x < cam.width; x += 2) {
          const int h = f.human_id.at<std::uint8_t>(y, x);
          const float z = f.depth_true.at<float>(y, x);
          if (h == 0 || f.part_id.at<std::uint8_t>(y, x) != 0 || !(z > 0)) continue;
          const auto& b = f.boxes[static_cast<std::size_t>(h - 1)];
          ASSERT_NE(b.carried, 0);
          ASSERT_EQ(f.dynamic_mask.at<std::uint8_t>(y, x), 255);
          const Eigen::Vector3d pw = f.T_world_cam * cam.back_project(x, y, z);
          const Eigen::Vector3d local =
              Eigen::AngleAxisd(-b.yaw, Eigen::Vector3d::UnitZ()) * (pw - b.center);
          ASSERT_TRUE((local.cwiseAbs() - b.size / 2).maxCoeff() < 0.02)
              << "frame " << i << " person " << h - 1;
          ++carried_seen[static_cast<std::size_t>(h - 1)];
        }
      }
    }
    EXPECT_TRUE(close);
    for (const auto& b : f0.boxes) {
      if (b.carried != 0) {
        EXPECT_GT(carried_seen[static_cast<std::size_t>(b.id)], 0);
      }
    }
    if (kCrowd[s] == Scenario::kCrowdBoard) {
      for (int c = 1; c <= 3; ++c) {
        EXPECT_TRUE(std::any_of(f0.boxes.begin(), f0.boxes.end(),
                                [&](const auto& b) { return b.carried == c; }));
      }
    }
  }
}

TEST(SynthCrowd, HandheldCameraRotatesTranslatesAndBlursWhereFast) {
  for (const Scenario sc : kCrowd) {
    SCOPED_TRACE(ds3d::synth::scenario_name(sc));
    const SyntheticScene scene({.scenario = sc, .num_frames = 150, .seed = 2});
    const Eigen::Isometry3d p0 = scene.camera_pose(scene.timestamp(0));
    double max_angle = 0;
    double max_shift = 0;
    for (std::size_t i = 0; i < scene.size(); ++i) {
      const Eigen::Isometry3d d = p0.inverse() * scene.camera_pose(scene.timestamp(i));
      max_angle = std::max(max_angle, Eigen::AngleAxisd(d.linear()).angle());
      max_shift = std::max(max_shift, d.translation().norm());
    }
    EXPECT_GT(max_angle, 0.05);
    EXPECT_GT(max_shift, 0.05);
  }
  // Blur follows the image motion: none where the camera turns slowly, some where it is fast.
  const SyntheticScene scene(
      {.scenario = Scenario::kCrowdHandheld, .num_frames = 150, .seed = 1, .camera = half_vga()});
  int blurred = 0;
  int sharp = 0;
  for (std::size_t i = 1; i < scene.size(); i += 3) {
    const auto f = scene.render(i);
    const Eigen::Isometry3d d = scene.camera_pose(scene.timestamp(i - 1)).inverse() * f.T_world_cam;
    const double rot_px = Eigen::AngleAxisd(d.linear()).angle() * half_vga().fx;
    if (f.blur_px > 0) {
      ++blurred;
      EXPECT_GE(f.blur_px, 1.5);
      EXPECT_GT(rot_px, 1.0) << "frame " << i;  // blurred while turning
    } else {
      ++sharp;
      EXPECT_LT(0.5 * rot_px, 1.5 + 2.0) << "frame " << i;  // a fast turn is never sharp
    }
  }
  EXPECT_GT(blurred, 5);
  EXPECT_GT(sharp, 5);
  EXPECT_EQ(
      SyntheticScene({.scenario = Scenario::kWalkingRpy, .num_frames = 60}).render(45).blur_px,
      0.0);
}

TEST(SynthCrowd, DeterministicBySeed) {
  for (const Scenario sc : kCrowd) {
    const SynthOptions o{.scenario = sc, .num_frames = 40, .seed = 5, .camera = half_vga()};
    SynthOptions o2 = o;
    o2.seed = 6;
    const auto a = SyntheticScene(o).render(33);
    const auto b = SyntheticScene(o).render(33);
    EXPECT_TRUE(same(a.rgb, b.rgb));
    EXPECT_TRUE(same(a.depth, b.depth));
    EXPECT_TRUE(same(a.human_id, b.human_id));
    EXPECT_FALSE(same(a.rgb, SyntheticScene(o2).render(33).rgb));
  }
}

// detections_noisy.jsonl: miss and false rates near the requested ones, misses in runs, same file
// for the same seed, readable by DetectionsFile.
TEST(SynthCrowd, NoisyDetectionsRatesAndDeterminism) {
  ds3d::PinholeCamera cam;
  cam.fx = cam.fy = 131.25;
  cam.cx = 79.5;
  cam.cy = 59.5;
  cam.width = 160;
  cam.height = 120;
  const SynthOptions opt{.scenario = Scenario::kCrowdCross,
                         .num_frames = 300,
                         .seed = 4,
                         .camera = cam,
                         .detection_miss = 0.2,
                         .detection_false = 0.1};
  const fs::path dir = fs::temp_directory_path() / ("ds3d_crowd_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  (void)ds3d::synth::generate_sequence(dir / "a", opt);
  (void)ds3d::synth::generate_sequence(dir / "b", opt);
  const std::string noisy = ds3d::test::read_file(dir / "a" / "detections_noisy.jsonl");
  EXPECT_EQ(noisy, ds3d::test::read_file(dir / "b" / "detections_noisy.jsonl"));
  const auto det = ds3d::DetectionsFile::read(dir / "a" / "detections_noisy.jsonl");
  ASSERT_EQ(det.frames().size(), 300U);
  const auto truth = ds3d::test::read_lines(dir / "a" / "boxes.jsonl");
  ASSERT_EQ(truth.size(), 300U);
  const int min_px = std::max(20, cam.width * cam.height / 500);
  int detectable = 0;
  int detected = 0;
  int false_frames = 0;
  for (std::size_t i = 0; i < 300; ++i) {
    const auto t = ds3d::detail::parse_json(truth[i]);
    for (const auto& b : t.at("boxes").as_array()) {
      detectable += b.at("visible_pixels").as_number() >= min_px ? 1 : 0;
    }
    int trues = 0;
    int falses = 0;
    for (const auto& d : det.frames()[i].detections) {
      EXPECT_TRUE(d.is_3d);
      EXPECT_EQ(d.cls, "person");
      (d.score > 0.8F ? trues : falses) += 1;
    }
    detected += trues;
    false_frames += falses > 0 ? 1 : 0;
  }
  ASSERT_GT(detectable, 300);
  const double miss = 1.0 - static_cast<double>(detected) / detectable;
  EXPECT_GT(miss, 0.1);
  EXPECT_LT(miss, 0.3);
  EXPECT_GT(false_frames / 300.0, 0.05);
  EXPECT_LT(false_frames / 300.0, 0.15);
  // Without detector errors, no noisy file.
  SynthOptions clean = opt;
  clean.num_frames = 2;
  clean.detection_miss = clean.detection_false = 0;
  (void)ds3d::synth::generate_sequence(dir / "c", clean);
  EXPECT_FALSE(fs::exists(dir / "c" / "detections_noisy.jsonl"));
  fs::remove_all(dir);
}

}  // namespace
