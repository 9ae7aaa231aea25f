// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Synthetic dynamic RGB-D generator: determinism, masks vs boxes, depth model, ORB texture,
// camera trajectories, the written TUM folder.
#include "ds3d/slam/synth.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/features2d.hpp>

#include "ds3d/detail/json.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "ds3d/slam/dataset.hpp"
#include "support/cli.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;
using ds3d::synth::Scenario;
using ds3d::synth::SyntheticScene;
using ds3d::synth::SynthOptions;

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

TEST(Synth, DeterministicBySeed) {
  const SyntheticScene a({.scenario = Scenario::kWalkingXyz, .num_frames = 5, .seed = 7});
  const SyntheticScene b({.scenario = Scenario::kWalkingXyz, .num_frames = 5, .seed = 7});
  const SyntheticScene c({.scenario = Scenario::kWalkingXyz, .num_frames = 5, .seed = 8});
  const auto fa = a.render(4);
  const auto fb = b.render(4);
  EXPECT_TRUE(same(fa.rgb, fb.rgb));
  EXPECT_TRUE(same(fa.depth, fb.depth));
  EXPECT_TRUE(same(fa.dynamic_mask, fb.dynamic_mask));
  EXPECT_FALSE(same(fa.rgb, c.render(4).rgb));
  EXPECT_THROW((void)a.render(5), ds3d::InvalidArgument);
}

TEST(Synth, RejectsBadOptions) {
  EXPECT_THROW(SyntheticScene({.num_frames = 0}), ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.num_humans = 5}), ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.fps = 0}), ds3d::InvalidArgument);
  SynthOptions o;
  o.camera.k1 = 0.1;
  EXPECT_THROW(SyntheticScene{o}, ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::synth::parse_scenario("walking"), ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.room_size = Eigen::Vector3d(3.0, 5, 2.8)}), ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.room_size = Eigen::Vector3d(4.5, 5, 9)}), ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.room_size = Eigen::Vector3d(4.5, NAN, 2.8)}),
               ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.extra_furniture = 13}), ds3d::InvalidArgument);
  EXPECT_THROW(SyntheticScene({.extra_furniture = -1}), ds3d::InvalidArgument);
  for (const char* n : {"static_room", "walking_static", "walking_xyz", "walking_halfsphere",
                        "walking_rpy", "sitting_static", "sitting_xyz"}) {
    EXPECT_EQ(ds3d::synth::scenario_name(ds3d::synth::parse_scenario(n)), n);
  }
}

TEST(Synth, MasksMatchHumansAndBoxes) {
  const SynthOptions opt{
      .scenario = Scenario::kWalkingStatic, .num_frames = 40, .seed = 3, .num_humans = 3};
  const SyntheticScene scene(opt);
  for (const std::size_t i : {std::size_t{0}, std::size_t{39}}) {
    const auto f = scene.render(i);
    ASSERT_EQ(f.boxes.size(), 3U);
    cv::Mat from_ids;
    cv::compare(f.human_id, 0, from_ids, cv::CMP_GT);
    EXPECT_TRUE(same(from_ids, f.dynamic_mask));
    int total = 0;
    for (const auto& b : f.boxes) {
      total += b.visible_pixels;
      EXPECT_GT(b.size.z(), 1.4);  // standing humans, 1.55-1.95 m
      EXPECT_LT(b.size.z(), 2.1);
      EXPECT_FALSE(b.sitting);
    }
    EXPECT_EQ(total, cv::countNonZero(f.dynamic_mask));
    EXPECT_GT(total, 1000);
    // Every human pixel, back-projected with the true depth, lies inside its own box.
    const cv::Mat loc = ds3d::synth::part_locations(f, opt.camera);
    int outside = 0;
    for (int y = 0; y < loc.rows; ++y) {
      for (int x = 0; x < loc.cols; ++x) {
        const auto h = f.human_id.at<std::uint8_t>(y, x);
        if (h == 0) continue;
        const auto& b = f.boxes[h - 1U];
        const Eigen::Vector3d pw =
            f.T_world_cam * opt.camera.back_project(x, y, f.depth_true.at<float>(y, x));
        const Eigen::Vector3d local =
            Eigen::AngleAxisd(-b.yaw, Eigen::Vector3d::UnitZ()) * (pw - b.center);
        if ((local.cwiseAbs() - 0.5 * b.size).maxCoeff() > 0.01) ++outside;
        const cv::Vec3f l = loc.at<cv::Vec3f>(y, x);
        for (int k = 0; k < 3; ++k) {
          EXPECT_GE(l[k], 0.0F);
          EXPECT_LE(l[k], 1.0F);
        }
      }
    }
    EXPECT_EQ(outside, 0);
    // Every part id is a human part, and only on human pixels.
    double max_part = 0;
    cv::minMaxLoc(f.part_id, nullptr, &max_part);
    EXPECT_LE(max_part, 10.0);
    EXPECT_EQ(cv::countNonZero(f.part_id), total);
  }
}

TEST(Synth, RoomSizeMovesTheWallsAndKeepsPeopleInside) {
  // The empty room seen with exact depth: a shallower room brings the far wall nearer.
  const auto median_depth = [](const Eigen::Vector3d& room) {
    const auto f = SyntheticScene({.scenario = Scenario::kStaticRoom,
                                   .num_frames = 1,
                                   .depth_noise = false,
                                   .room_size = room})
                       .render(0);
    std::vector<float> z;
    for (int y = 0; y < f.depth_true.rows; ++y) {
      for (int x = 0; x < f.depth_true.cols; ++x) {
        if (f.depth_true.at<float>(y, x) > 0) z.push_back(f.depth_true.at<float>(y, x));
      }
    }
    std::nth_element(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(z.size() / 2), z.end());
    return z[z.size() / 2];
  };
  EXPECT_LT(median_depth(Eigen::Vector3d(3.6, 5, 2.8)) + 0.3F,
            median_depth(Eigen::Vector3d(4.5, 5, 2.8)));
  // Walkers of a large room walk inside it, over the whole room.
  const Eigen::Vector3d room(7.0, 9.0, 3.0);
  const SyntheticScene big({.scenario = Scenario::kWalkingStatic,
                            .num_frames = 900,
                            .seed = 5,
                            .num_humans = 4,
                            .room_size = room});
  double max_y = 0;
  for (std::size_t i = 0; i < 900; i += 60) {
    for (const auto& b : big.render(i).boxes) {
      EXPECT_GT(b.center.x(), 0.5);
      EXPECT_LT(b.center.x(), room.x() - 0.5);
      EXPECT_GT(b.center.y(), 0.5);
      EXPECT_LT(b.center.y(), room.y() - 0.5);
      max_y = std::max(max_y, b.center.y());
    }
  }
  EXPECT_GT(max_y, 5.0);  // beyond the default room's width
}

TEST(Synth, ExtraFurnitureLeavesPeopleAndCameraAlone) {
  const SynthOptions base{
      .scenario = Scenario::kWalkingXyz, .num_frames = 300, .seed = 9, .num_humans = 3};
  SynthOptions cluttered = base;
  cluttered.extra_furniture = 8;
  const SyntheticScene a(base);
  const SyntheticScene b(cluttered);
  int nearer = 0;
  for (const std::size_t i : {std::size_t{0}, std::size_t{150}, std::size_t{299}}) {
    const auto fa = a.render(i);
    const auto fb = b.render(i);
    EXPECT_TRUE(fa.T_world_cam.isApprox(fb.T_world_cam, 0.0));
    ASSERT_EQ(fa.boxes.size(), fb.boxes.size());
    for (std::size_t k = 0; k < fa.boxes.size(); ++k) {
      EXPECT_EQ(fa.boxes[k].center, fb.boxes[k].center);  // the same walks
      EXPECT_EQ(fa.boxes[k].size, fb.boxes[k].size);
    }
    // Furniture only ever stands in front of the static scene: where a pixel got nearer, it is
    // not a person's in either scene.
    for (int y = 0; y < fa.depth_true.rows; ++y) {
      for (int x = 0; x < fa.depth_true.cols; ++x) {
        const float za = fa.depth_true.at<float>(y, x);
        const float zb = fb.depth_true.at<float>(y, x);
        if (zb > 0 && (za == 0 || zb < za - 0.05F)) {
          ++nearer;
          EXPECT_EQ(fb.human_id.at<std::uint8_t>(y, x), 0);
        }
      }
    }
  }
  EXPECT_GT(nearer, 2000);  // the furniture is in view
}

TEST(Synth, StaticRoomHasNoHumansAndSittingHumansSit) {
  const auto f = SyntheticScene({.scenario = Scenario::kStaticRoom, .num_frames = 1}).render(0);
  EXPECT_TRUE(f.boxes.empty());
  EXPECT_EQ(cv::countNonZero(f.dynamic_mask), 0);
  const SyntheticScene sit({.scenario = Scenario::kSittingStatic, .num_frames = 60, .seed = 2});
  const auto a = sit.render(0);
  const auto b = sit.render(59);
  ASSERT_EQ(a.boxes.size(), 2U);
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_TRUE(a.boxes[k].sitting);
    EXPECT_LT(a.boxes[k].size.z(), 1.5);                              // seated: lower box
    EXPECT_LT((a.boxes[k].center - b.boxes[k].center).norm(), 0.15);  // moves only a little
    EXPECT_GT(a.boxes[k].visible_pixels, 500);
  }
}

TEST(Synth, KinectLikeDepth) {
  const SyntheticScene exact(
      {.scenario = Scenario::kWalkingXyz, .num_frames = 1, .seed = 4, .depth_noise = false});
  const SyntheticScene noisy({.scenario = Scenario::kWalkingXyz, .num_frames = 1, .seed = 4});
  const auto fe = exact.render(0);
  const auto fn = noisy.render(0);
  double sum_sq_norm = 0;
  int n = 0;
  int holes_valid = 0;
  for (int y = 0; y < fe.depth.rows; ++y) {
    for (int x = 0; x < fe.depth.cols; ++x) {
      const float zt = fe.depth_true.at<float>(y, x);
      ASSERT_GT(zt, 0.0F);  // closed room: every pixel hits something
      EXPECT_NEAR(fe.depth.at<std::uint16_t>(y, x) / 5000.0, zt, 1.01e-4);
      const auto d = fn.depth.at<std::uint16_t>(y, x);
      if (d == 0) {
        if (zt <= 4.5F) ++holes_valid;
        continue;
      }
      EXPECT_LE(zt, 4.5F);
      const double z = d / 5000.0;
      const double sigma = 1.425e-3 * zt * zt;
      // noise plus 1/8-pixel disparity quantisation (step z^2 / (8 * 0.075 * 525))
      const double q = zt * zt / (8 * 0.075 * 525.0);
      sum_sq_norm += (z - zt) * (z - zt) / (sigma * sigma + q * q / 12);
      ++n;
    }
  }
  ASSERT_GT(n, 200000);
  EXPECT_NEAR(std::sqrt(sum_sq_norm / n), 1.0, 0.15);  // the error has the modelled spread
  EXPECT_GT(holes_valid, 200);                         // holes at depth edges
  EXPECT_LT(holes_valid, 640 * 480 / 10);
}

TEST(Synth, TexturedEnoughForOrb) {
  const auto f =
      SyntheticScene({.scenario = Scenario::kStaticRoom, .num_frames = 1, .seed = 9}).render(0);
  std::vector<cv::KeyPoint> kps;
  cv::ORB::create(1000)->detect(f.rgb, kps);
  EXPECT_GE(kps.size(), 900U);
  // spread over the image: every quadrant has features
  int quad[4] = {0, 0, 0, 0};
  for (const auto& k : kps) ++quad[(k.pt.x > 320 ? 1 : 0) + (k.pt.y > 240 ? 2 : 0)];
  for (const int q : quad) EXPECT_GT(q, 50);
}

TEST(Synth, CameraTrajectoriesMoveAsNamed) {
  const auto motion = [](Scenario s) {
    const SyntheticScene sc({.scenario = s, .num_frames = 1});
    double max_t = 0;
    double max_r = 0;
    const Eigen::Isometry3d p0 = sc.camera_pose(sc.timestamp(0));
    for (double t = 0; t < 12; t += 0.1) {
      const Eigen::Isometry3d d = p0.inverse() * sc.camera_pose(sc.timestamp(0) + t);
      max_t = std::max(max_t, d.translation().norm());
      max_r = std::max(max_r, Eigen::AngleAxisd(d.linear()).angle());
    }
    return std::pair{max_t, max_r};
  };
  EXPECT_LT(motion(Scenario::kWalkingStatic).first, 0.02);
  EXPECT_LT(motion(Scenario::kWalkingStatic).second, 0.02);
  EXPECT_GT(motion(Scenario::kWalkingXyz).first, 0.3);
  EXPECT_LT(motion(Scenario::kWalkingXyz).second, 0.02);
  EXPECT_GT(motion(Scenario::kWalkingRpy).second, 0.4);
  EXPECT_LT(motion(Scenario::kWalkingRpy).first, 0.02);
  EXPECT_GT(motion(Scenario::kWalkingHalfsphere).first, 0.5);
  EXPECT_GT(motion(Scenario::kWalkingHalfsphere).second, 0.5);
}

TEST(Synth, WritesATumFolderThatReadsBack) {
  const fs::path dir = fs::temp_directory_path() / ("ds3d_synth_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const auto sum = ds3d::synth::generate_sequence(
      dir, {.scenario = Scenario::kWalkingXyz, .num_frames = 6, .seed = 11, .write_parts = true});
  EXPECT_EQ(sum.frames, 6U);
  EXPECT_GT(sum.dynamic_pixels, 0U);
  const auto ds = ds3d::RgbdDataset::open(dir);
  ASSERT_EQ(ds.size(), 6U);
  EXPECT_EQ(ds.camera().fx, 525.0);
  const SyntheticScene scene({.scenario = Scenario::kWalkingXyz, .num_frames = 6, .seed = 11});
  const auto f = ds.frame(3);
  const auto r = scene.render(3);
  EXPECT_TRUE(same(f.rgb, r.rgb));
  EXPECT_TRUE(same(f.depth, r.depth));
  // ground truth (100 Hz, analytic) covers the frames and agrees with the rendered poses
  ASSERT_TRUE(ds.groundtruth_path().has_value());
  const auto gt = ds3d::read_tum_trajectory(*ds.groundtruth_path());
  ASSERT_GE(gt.size(), 20U);
  EXPECT_LE(gt.front().timestamp, scene.timestamp(0));
  EXPECT_GE(gt.back().timestamp, scene.timestamp(5));
  for (const auto& p : gt) {
    EXPECT_LT((p.T_world_cam.matrix() - scene.camera_pose(p.timestamp).matrix()).norm(), 1e-9);
  }
  EXPECT_TRUE(r.T_world_cam.isApprox(scene.camera_pose(scene.timestamp(3)), 1e-12));
  // boxes.jsonl: one object per frame
  const auto lines = ds3d::test::read_lines(dir / "boxes.jsonl");
  ASSERT_EQ(lines.size(), 6U);
  const auto j = ds3d::detail::parse_json(lines[3]);
  EXPECT_EQ(j.at("frame").as_int(), 3);
  EXPECT_EQ(j.at("boxes").size(), 2U);
  EXPECT_EQ(j.at("boxes").at(0).at("visible_pixels").as_int(), r.boxes[0].visible_pixels);
  // masks and parts written; no temporary files anywhere
  for (const char* sub : {"mask", "parts", "parts_loc", "rgb", "depth"}) {
    std::size_t n = 0;
    for (const auto& e : fs::directory_iterator(dir / sub)) {
      EXPECT_EQ(e.path().extension(), ".png") << e.path();
      EXPECT_EQ(e.path().filename().string()[0] == '.', false) << e.path();
      ++n;
    }
    EXPECT_EQ(n, 6U) << sub;
  }
  fs::remove_all(dir);
}

// An earlier sequence is never mixed with a new one: a non-empty folder is refused unless
// overwrite, which replaces it whole; no temporary folder is left beside it.
TEST(Synth, RefusesANonEmptyFolderUnlessOverwrite) {
  const fs::path root = fs::temp_directory_path() / ("ds3d_synth_ow_" + std::to_string(::getpid()));
  fs::remove_all(root);
  const fs::path dir = root / "seq";
  const SynthOptions three{.scenario = Scenario::kStaticRoom, .num_frames = 3, .seed = 1};
  (void)ds3d::synth::generate_sequence(dir, three);
  std::ofstream(dir / "stale.txt") << "from an earlier run";
  try {
    (void)ds3d::synth::generate_sequence(dir, {.scenario = Scenario::kStaticRoom, .num_frames = 2});
    ADD_FAILURE() << "non-empty folder accepted";
  } catch (const ds3d::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("'" + dir.string() + "' is not empty"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(ds3d::RgbdDataset::open(dir).size(), 3U);  // untouched
  EXPECT_TRUE(fs::exists(dir / "stale.txt"));
  (void)ds3d::synth::generate_sequence(dir, {.scenario = Scenario::kStaticRoom, .num_frames = 2},
                                       /*overwrite=*/true);
  EXPECT_EQ(ds3d::RgbdDataset::open(dir).size(), 2U);
  EXPECT_FALSE(fs::exists(dir / "stale.txt"));
  // Bad options fail before anything is touched.
  EXPECT_THROW((void)ds3d::synth::generate_sequence(dir, {.num_frames = 0}, true),
               ds3d::InvalidArgument);
  EXPECT_EQ(ds3d::RgbdDataset::open(dir).size(), 2U);
  // An empty folder is fine without overwrite; a file is not a folder.
  fs::create_directories(root / "empty");
  (void)ds3d::synth::generate_sequence(root / "empty", {.num_frames = 1});
  std::ofstream(root / "file") << "x";
  EXPECT_THROW((void)ds3d::synth::generate_sequence(root / "file", {.num_frames = 1}, true),
               ds3d::IoError);
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(root)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"empty", "file", "seq"}));  // no .seq.tmp* left
  // The tool: refused without --overwrite (exit 1, the folder named), replaced with it.
  if (fs::exists(ds3d::test::tool_path("ds3d-synth"))) {
    auto r = ds3d::test::run_tool("ds3d-synth", "'" + dir.string() + "' --frames 1");
    EXPECT_EQ(r.code, 1) << r.output;
    EXPECT_NE(r.output.find("is not empty"), std::string::npos) << r.output;
    r = ds3d::test::run_tool("ds3d-synth", "'" + dir.string() + "' --frames 1 --overwrite");
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(ds3d::RgbdDataset::open(dir).size(), 1U);
    // Integers out of their type's range and non-numbers are errors naming the option, before
    // anything is written (2^40 frames used to wrap to 0).
    for (const std::string bad : {"--frames 1099511627776", "--seed -1", "--humans 1x", "--fps inf",
                                  "--room 1,2,nan", "--furniture 99999999999"}) {
      r = ds3d::test::run_tool("ds3d-synth", "'" + dir.string() + "' --overwrite " + bad);
      EXPECT_EQ(r.code, 1) << bad << ": " << r.output;
      EXPECT_NE(r.output.find(bad.substr(0, bad.find(' ')) + ": expected"), std::string::npos)
          << r.output;
      EXPECT_EQ(ds3d::RgbdDataset::open(dir).size(), 1U) << bad;
    }
  }
  fs::remove_all(root);
}

}  // namespace
