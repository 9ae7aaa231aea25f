// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// TUM/Bonn folder reading: association, camera presets and camera.txt, clear errors, real data.
#include "ds3d/slam/dataset.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "ds3d/errors.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;

void write_text(const fs::path& p, const std::string& s) {
  std::ofstream out(p, std::ios::binary);
  out << s;
}

// A tiny TUM-layout folder: 4 rgb frames, 4 depth frames, one depth too far to associate.
class TinyFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("ds3d_dataset_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "rgb");
    fs::create_directories(dir_ / "depth");
    const double rgb_t[4] = {10.000, 10.033, 10.066, 10.100};
    const double depth_t[4] = {10.001, 10.030, 10.075, 10.300};  // 10.300: no partner
    std::string rgb_txt = "# color images\n# timestamp filename\n";
    std::string depth_txt = "# depth\r\n";
    for (int i = 0; i < 4; ++i) {
      cv::Mat rgb(6, 8, CV_8UC3, cv::Scalar(10 * i, 20, 30));
      cv::Mat depth(6, 8, CV_16UC1, cv::Scalar(1000 + i));
      const std::string rn = "rgb/" + std::to_string(i) + ".png";
      const std::string dn = "depth/" + std::to_string(i) + ".png";
      cv::imwrite((dir_ / rn).string(), rgb);
      cv::imwrite((dir_ / dn).string(), depth);
      rgb_txt += std::to_string(rgb_t[i]) + " " + rn + "\n";
      depth_txt += std::to_string(depth_t[i]) + "\t" + dn + "\r\n";
    }
    write_text(dir_ / "rgb.txt", rgb_txt);
    write_text(dir_ / "depth.txt", depth_txt);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(TinyFolder, AssociatesAndStreamsFrames) {
  const auto ds = ds3d::RgbdDataset::open(dir_);
  // 10.000-10.001, 10.033-10.030, 10.066-10.075 (0.009), 10.100 has none within 0.02.
  ASSERT_EQ(ds.size(), 3U);
  EXPECT_EQ(ds.directory(), dir_);
  EXPECT_FALSE(ds.groundtruth_path().has_value());
  EXPECT_EQ(ds.camera().fx, 525.0);  // no camera.txt: ROS default
  const auto f = ds.frame(2);
  EXPECT_EQ(f.index, 2U);
  EXPECT_DOUBLE_EQ(f.timestamp, 10.066);
  EXPECT_DOUBLE_EQ(f.depth_timestamp, 10.075);
  ASSERT_EQ(f.rgb.type(), CV_8UC3);
  ASSERT_EQ(f.depth.type(), CV_16UC1);
  EXPECT_EQ(f.depth.at<std::uint16_t>(0, 0), 1002);
  EXPECT_EQ(f.rgb.at<cv::Vec3b>(0, 0)[0], 20);  // B channel written as 10*i
  EXPECT_THROW((void)ds.frame(3), ds3d::InvalidArgument);

  const auto shifted = ds3d::RgbdDataset::open(dir_, {.max_difference = 0.005});
  EXPECT_EQ(shifted.size(), 2U);
  EXPECT_THROW((void)ds3d::RgbdDataset::open(dir_, {.max_difference = -1}), ds3d::InvalidArgument);
}

TEST_F(TinyFolder, CameraPrecedence) {
  write_text(dir_ / "camera.txt", "# cam\nfx 500\nfy 501\ncx 3.5\ncy 2.5\ndepth_scale 1000\n");
  write_text(dir_ / "groundtruth.txt", "1 0 0 0 0 0 0 1\n");
  EXPECT_EQ(ds3d::RgbdDataset::open(dir_).camera().fx, 500.0);
  EXPECT_EQ(ds3d::RgbdDataset::open(dir_).camera().depth_scale, 1000.0);
  EXPECT_TRUE(ds3d::RgbdDataset::open(dir_).groundtruth_path().has_value());
  const auto ds = ds3d::RgbdDataset::open(dir_, {.camera = ds3d::camera_preset("tum3")});
  EXPECT_EQ(ds.camera().fx, 535.4);
}

TEST_F(TinyFolder, ClearErrors) {
  const auto message_of = [](auto&& fn) -> std::string {
    try {
      fn();
    } catch (const std::exception& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_THROW((void)ds3d::RgbdDataset::open(dir_ / "nope"), ds3d::IoError);
  // 8-bit depth
  cv::imwrite((dir_ / "depth/1.png").string(), cv::Mat(6, 8, CV_8UC1, cv::Scalar(3)));
  const auto ds = ds3d::RgbdDataset::open(dir_);
  EXPECT_NE(message_of([&] { (void)ds.frame(1); }).find("16-bit"), std::string::npos);
  // unreadable image
  write_text(dir_ / "rgb/0.png", "not a png");
  EXPECT_NE(message_of([&] { (void)ds.frame(0); }).find("cannot read rgb image"),
            std::string::npos);
  // a timestamp that is not a number
  write_text(dir_ / "rgb.txt", "10.0 rgb/0.png\nabc rgb/1.png\n");
  const std::string m = message_of([&] { (void)ds3d::RgbdDataset::open(dir_); });
  EXPECT_NE(m.find("line 2"), std::string::npos) << m;
  EXPECT_NE(m.find("'abc'"), std::string::npos) << m;
  // missing list
  write_text(dir_ / "rgb.txt", "10.0 rgb/0.png\n");
  fs::remove(dir_ / "depth.txt");
  EXPECT_NE(message_of([&] { (void)ds3d::RgbdDataset::open(dir_); }).find("depth.txt"),
            std::string::npos);
}

// A JPEG cut short decodes with only a libjpeg warning (cv::imread returns a partly grey image):
// frame() must reject it, naming the file.
TEST_F(TinyFolder, TruncatedJpegIsAnError) {
  std::vector<std::uint8_t> jpg;
  cv::Mat noise(6, 8, CV_8UC3);
  cv::randu(noise, 0, 255);
  ASSERT_TRUE(cv::imencode(".jpg", noise, jpg));
  ASSERT_GE(jpg.size(), 100U);
  EXPECT_EQ(jpg[jpg.size() - 2], 0xFF);
  EXPECT_EQ(jpg[jpg.size() - 1], 0xD9);
  write_text(dir_ / "rgb/0.png", std::string(jpg.begin(), jpg.end()));  // whole: fine
  const auto ds = ds3d::RgbdDataset::open(dir_);
  EXPECT_EQ(ds.frame(0).rgb.size(), cv::Size(8, 6));
  write_text(dir_ / "rgb/0.png", std::string(jpg.begin(), jpg.end() - 40));
  ASSERT_FALSE(cv::imread((dir_ / "rgb/0.png").string()).empty());  // libjpeg only warns
  try {
    (void)ds.frame(0);
    ADD_FAILURE() << "truncated JPEG accepted";
  } catch (const ds3d::IoError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("rgb/0.png' is a truncated JPEG"), std::string::npos) << m;
  }
}

// Duplicate stamps and long gaps are counted, not silently dropped.
TEST_F(TinyFolder, DiagnosticsCountDuplicatesAndGaps) {
  const auto clean = ds3d::RgbdDataset::open(dir_);
  EXPECT_EQ(clean.diagnostics().rgb_duplicates, 0U);
  EXPECT_EQ(clean.diagnostics().large_gaps, 0U);
  EXPECT_EQ(clean.diagnostics().unassociated_rgb, 1U);  // 10.100
  write_text(dir_ / "rgb.txt",
             "10.000 rgb/0.png\n10.033 rgb/1.png\n10.033 rgb/2.png\n1010.066 rgb/2.png\n");
  write_text(dir_ / "depth.txt", "10.001 depth/0.png\n10.030 depth/1.png\n1010.07 depth/2.png\n");
  const auto ds = ds3d::RgbdDataset::open(dir_);
  const auto& d = ds.diagnostics();
  EXPECT_EQ(ds.size(), 3U);
  EXPECT_EQ(d.rgb_duplicates, 1U);
  EXPECT_DOUBLE_EQ(d.first_rgb_duplicate, 10.033);
  EXPECT_EQ(d.depth_duplicates, 0U);
  EXPECT_EQ(d.large_gaps, 1U);
  EXPECT_DOUBLE_EQ(d.first_gap_start, 10.033);
  EXPECT_NEAR(d.first_gap_seconds, 1000.033, 1e-9);
  EXPECT_GE(d.gap_threshold, 1.0);
}

TEST(CameraPreset, KnownNamesAndFiles) {
  EXPECT_EQ(ds3d::camera_preset("tum_ros").fx, 525.0);
  EXPECT_EQ(ds3d::camera_preset("tum_ros").cy, 239.5);
  EXPECT_EQ(ds3d::camera_preset("tum3").fy, 539.2);
  EXPECT_FALSE(ds3d::camera_preset("tum3").has_distortion());
  EXPECT_TRUE(ds3d::camera_preset("tum2").has_distortion());
  EXPECT_THROW((void)ds3d::camera_preset("kinect"), ds3d::InvalidArgument);
  for (const auto& [file, preset] : {std::pair{"dataset/bonn_camera.txt", "bonn"},
                                     std::pair{"dataset/tum1_camera.txt", "tum1"}}) {
    const auto c = ds3d::read_camera_file(ds3d::test::data_path(file));
    const auto p = ds3d::camera_preset(preset);
    EXPECT_EQ(c.fx, p.fx) << preset;
    EXPECT_EQ(c.fy, p.fy);
    EXPECT_EQ(c.cx, p.cx);
    EXPECT_EQ(c.cy, p.cy);
    EXPECT_EQ(c.k1, p.k1);
    EXPECT_EQ(c.k2, p.k2);
    EXPECT_EQ(c.p1, p.p1);
    EXPECT_EQ(c.p2, p.p2);
    EXPECT_EQ(c.k3, p.k3);
    EXPECT_EQ(c.depth_scale, 5000.0);
  }
}

// A folder without camera.txt: standard TUM / Bonn folder names select their calibrated preset
// (one info line on stderr), any other name the ROS default with a one-line warning.
TEST(CameraPreset, FromFolderNameWithoutCameraFile) {
  const fs::path root = fs::temp_directory_path() / ("ds3d_folders_" + std::to_string(::getpid()));
  const std::pair<const char*, const char*> cases[] = {
      {"rgbd_dataset_freiburg1_xyz", "tum1"},
      {"rgbd_dataset_freiburg2_desk", "tum2"},
      {"rgbd_dataset_freiburg3_walking_xyz", "tum3"},
      {"rgbd_bonn_crowd", "bonn"},
      {"my_recording", nullptr},
      {"freiburg1_xyz", nullptr}};
  for (const auto& [name, preset] : cases) {
    SCOPED_TRACE(name);
    const fs::path dir = root / name;
    fs::create_directories(dir);
    write_text(dir / "rgb.txt", "1.0 rgb/0.png\n");
    write_text(dir / "depth.txt", "1.0 depth/0.png\n");
    ::testing::internal::CaptureStderr();
    const auto ds = ds3d::RgbdDataset::open(dir);
    const std::string err = ::testing::internal::GetCapturedStderr();
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    const auto p = ds3d::camera_preset(preset != nullptr ? preset : "tum_ros");
    EXPECT_EQ(ds.camera().fx, p.fx);
    EXPECT_EQ(ds.camera().cy, p.cy);
    EXPECT_EQ(ds.camera().k1, p.k1);
    if (preset != nullptr) {
      EXPECT_EQ(ds3d::camera_preset_for_folder(dir / ""), std::string(preset));
      EXPECT_NE(err.find("info"), std::string::npos) << err;
      EXPECT_NE(err.find(std::string("'") + preset + "'"), std::string::npos) << err;
    } else {
      EXPECT_FALSE(ds3d::camera_preset_for_folder(dir).has_value());
      EXPECT_NE(err.find("WARNING"), std::string::npos) << err;
      EXPECT_NE(err.find("fx 525"), std::string::npos) << err;
    }
    // camera.txt still wins, silently.
    write_text(dir / "camera.txt", "fx 500\nfy 501\ncx 3.5\ncy 2.5\n");
    ::testing::internal::CaptureStderr();
    EXPECT_EQ(ds3d::RgbdDataset::open(dir).camera().fx, 500.0);
    EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  }
  fs::remove_all(root);
}

TEST(CameraFile, RejectsBadContent) {
  EXPECT_THROW((void)ds3d::parse_camera_text("fx 1\nfy 1\ncx 1\n"), ds3d::IoError);  // no cy
  EXPECT_THROW((void)ds3d::parse_camera_text("fx 1\nfy 1\ncx 1\ncy 1\nfoo 2\n"), ds3d::IoError);
  EXPECT_THROW((void)ds3d::parse_camera_text("fx 1\nfx 1\nfy 1\ncx 1\ncy 1\n"), ds3d::IoError);
  EXPECT_THROW((void)ds3d::parse_camera_text("fx -1\nfy 1\ncx 1\ncy 1\n"), ds3d::IoError);
  EXPECT_THROW((void)ds3d::parse_camera_text("fx nan\nfy 1\ncx 1\ncy 1\n"), ds3d::IoError);
  EXPECT_THROW((void)ds3d::parse_camera_text("fx 1 2\nfy 1\ncx 1\ncy 1\n"), ds3d::IoError);
  EXPECT_THROW((void)ds3d::read_camera_file("/nonexistent/camera.txt"), ds3d::IoError);
  const auto c = ds3d::parse_camera_text("fx 1\nfy 2\ncx 3\ncy 4\nwidth 320\nheight 240\n");
  EXPECT_EQ(c.width, 320);
  EXPECT_EQ(c.height, 240);
}

TEST(CameraFile, RejectsImplausibleIntrinsics) {
  const auto message_of = [](const std::string& text) -> std::string {
    try {
      (void)ds3d::parse_camera_text(text, "cam.txt");
    } catch (const ds3d::IoError& e) {
      return e.what();
    }
    return "accepted";
  };
  const std::string ok = "fy 525\ncy 239.5\n";
  for (const auto& [line, key, value] :
       {std::tuple{"fx 1e-300\ncx 319.5\n", "fx", "1e-300"},
        std::tuple{"fx 2e5\ncx 319.5\n", "fx", "200000"},
        std::tuple{"fx 525\ncx 1.5e308\n", "cx", "1.5e+308"},
        std::tuple{"fx 525\ncx -700\n", "cx", "-700"},
        std::tuple{"fx 525\ncx 319.5\ndepth_scale 1e-300\n", "depth_scale", "1e-300"}}) {
    const std::string msg = message_of(std::string(line) + ok);
    EXPECT_NE(msg.find(std::string("ds3d::read_camera_file: cam.txt: ") + key + " must be in"),
              std::string::npos)
        << msg;
    EXPECT_NE(msg.find(std::string("(got ") + value + ")"), std::string::npos) << msg;
  }
  // Small synthetic cameras and a principal point just off the image stay accepted.
  EXPECT_EQ(message_of("fx 1\nfy 30\ncx -20\ncy 40\nwidth 32\nheight 24\n"), "accepted");
}

// Real recorded data (skipped when ../shared/data is absent).
TEST(RealData, TumAndBonnFolders) {
  const fs::path root = ds3d::test::shared_data_dir();
  if (root.empty()) GTEST_SKIP() << "no shared data (set DS3D_DATA_DIR)";
  for (const char* name : {"tum_fr1_xyz_first400", "bonn_crowd_first300"}) {
    SCOPED_TRACE(name);
    if (!fs::exists(root / name)) continue;
    const auto ds = ds3d::RgbdDataset::open(root / name);
    EXPECT_GT(ds.size(), 250U);
    ASSERT_TRUE(ds.groundtruth_path().has_value());
    for (const std::size_t i : {std::size_t{0}, ds.size() - 1}) {
      const auto f = ds.frame(i);
      EXPECT_EQ(f.rgb.cols, 640);
      EXPECT_EQ(f.rgb.rows, 480);
      EXPECT_EQ(f.depth.type(), CV_16UC1);
      EXPECT_LT(std::abs(f.timestamp - f.depth_timestamp), 0.02);
      EXPECT_GT(cv::countNonZero(f.depth), 640 * 480 / 2);
    }
    for (std::size_t i = 1; i < ds.size(); ++i) {
      EXPECT_LT(ds.entries()[i - 1].timestamp, ds.entries()[i].timestamp);
    }
  }
}

}  // namespace
