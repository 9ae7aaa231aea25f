// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// MaskSource: per-frame mask images matched by timestamp; errors name the folder or file.
#include "ds3d/slam/dynamic/mask_source.hpp"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "ds3d/errors.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"

namespace {

namespace fs = std::filesystem;
using ds3d::slam::FrameInput;
using ds3d::slam::MaskSource;

ds3d::PinholeCamera small_camera() {
  ds3d::PinholeCamera c;
  c.width = 32;
  c.height = 24;
  c.cx = 15.5;
  c.cy = 11.5;
  return c;
}

fs::path make_dir(const char* name) {
  const fs::path d = fs::temp_directory_path() / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

TEST(MaskSource, ReturnsTheNearestMaskWithinMaxDt) {
  const fs::path d = make_dir("ds3d_mask_source_nearest");
  cv::Mat a(24, 32, CV_8UC1, cv::Scalar(0));
  a.at<std::uint8_t>(5, 7) = 255;
  cv::imwrite((d / "100.000000.png").string(), a);
  cv::imwrite((d / "100.100000.png").string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(1)));
  std::ofstream(d / "notes.txt") << "not a mask\n";
  MaskSource src(d, 0.02);
  FrameInput f;
  f.timestamp = 100.01;
  const auto o = src.detect(f, small_camera());
  ASSERT_FALSE(o.pixel_mask.empty());
  EXPECT_EQ(cv::countNonZero(o.pixel_mask), 1);
  EXPECT_NE(o.pixel_mask.at<std::uint8_t>(5, 7), 0);
  f.timestamp = 100.09;
  EXPECT_EQ(cv::countNonZero(src.detect(f, small_camera()).pixel_mask), 32 * 24);
  f.timestamp = 100.05;  // 0.05 s from both: no mask
  EXPECT_TRUE(src.detect(f, small_camera()).pixel_mask.empty());
  EXPECT_EQ(src.num_matched(), 2U);
  EXPECT_EQ(src.num_unmatched(), 1U);
  auto any = ds3d::slam::make_dynamic_source("mask:" + d.string());
  EXPECT_EQ(any->name(), "mask");
}

TEST(MaskSource, BadInputIsAClearError) {
  EXPECT_THROW(MaskSource("/nonexistent/ds3d_masks"), ds3d::IoError);
  const fs::path empty = make_dir("ds3d_mask_source_empty");
  EXPECT_THROW(MaskSource{empty}, ds3d::IoError);
  const fs::path d = make_dir("ds3d_mask_source_size");
  cv::imwrite((d / "5.png").string(), cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)));
  EXPECT_THROW(MaskSource(d, -1.0), ds3d::InvalidArgument);
  MaskSource src(d);
  FrameInput f;
  f.timestamp = 5.0;
  try {
    (void)src.detect(f, small_camera());
    FAIL() << "expected IoError";
  } catch (const ds3d::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("5.png"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)ds3d::slam::make_dynamic_source("mask:"), ds3d::InvalidArgument);
}

}  // namespace
