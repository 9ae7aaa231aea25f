// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/orb_features.hpp"

#include <array>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "ds3d/errors.hpp"
#include "support/synthetic.hpp"

namespace {

using ds3d::slam::OrbExtractor;
using ds3d::slam::OrbParams;

// Seeded clutter of grey rectangles and discs: texture everywhere, like a desk scene.
cv::Mat textured_image(std::uint64_t seed, int w = 640, int h = 480) {
  ds3d::test::Rng rng(seed);
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(90, 90, 90));
  for (int i = 0; i < 1500; ++i) {
    const cv::Point c(static_cast<int>(rng.uniform(0, w)), static_cast<int>(rng.uniform(0, h)));
    const auto g = rng.uniform(0, 255);
    const cv::Scalar col(g, rng.uniform(0, 255), g);
    if (i % 2 == 0) {
      cv::circle(img, c, static_cast<int>(rng.uniform(2, 12)), col, cv::FILLED);
    } else {
      cv::rectangle(
          img,
          {c.x, c.y, static_cast<int>(rng.uniform(3, 25)), static_cast<int>(rng.uniform(3, 25))},
          col, cv::FILLED);
    }
  }
  cv::GaussianBlur(img, img, {3, 3}, 0.8);
  return img;
}

ds3d::PinholeCamera plain_camera() {
  ds3d::PinholeCamera c;
  return c;
}

TEST(OrbExtractor, ExtractsAboutTheRequestedNumberSpreadOverTheImage) {
  const OrbExtractor ex;
  const auto f = ex.extract(textured_image(1), {}, plain_camera());
  EXPECT_GE(f.size(), 900U);
  EXPECT_LE(f.size(), 1000U);
  EXPECT_EQ(f.descriptors.rows, static_cast<int>(f.size()));
  EXPECT_EQ(f.descriptors.cols, 32);
  // Every cell of a 4x4 partition of the image gets a fair share (uniform would be 1/16).
  std::array<int, 16> counts{};
  std::array<int, 8> per_level{};
  for (const auto& k : f.keypoints) {
    const int cx = std::min(3, static_cast<int>(k.pt.x / 160.0F));
    const int cy = std::min(3, static_cast<int>(k.pt.y / 120.0F));
    ++counts[static_cast<std::size_t>(cy * 4 + cx)];
    ASSERT_GE(k.octave, 0);
    ASSERT_LT(k.octave, 8);
    ++per_level[static_cast<std::size_t>(k.octave)];
  }
  for (const int c : counts) EXPECT_GT(c, static_cast<int>(f.size()) / 40);
  // The geometric level schedule puts the most features on level 0 and some on every level.
  EXPECT_GT(per_level[0], per_level[7]);
  for (const int c : per_level) EXPECT_GT(c, 0);
}

TEST(OrbExtractor, DeterministicAndThreadSafe) {
  const OrbExtractor ex;
  const cv::Mat img = textured_image(2);
  const auto a = ex.extract(img, {}, plain_camera());
  ds3d::slam::OrbFeatures b;
  ds3d::slam::OrbFeatures c;
  std::thread t1([&] { b = ex.extract(img, {}, plain_camera()); });
  std::thread t2([&] { c = ex.extract(img, {}, plain_camera()); });
  t1.join();
  t2.join();
  for (const auto* o : {&b, &c}) {
    ASSERT_EQ(o->size(), a.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(o->keypoints[i].pt, a.keypoints[i].pt);
      EXPECT_EQ(o->keypoints[i].angle, a.keypoints[i].angle);
    }
    EXPECT_EQ(cv::norm(o->descriptors, a.descriptors, cv::NORM_HAMMING), 0.0);
  }
}

TEST(OrbExtractor, RotatedImageGivesMatchingDescriptors) {
  // Rotation invariance of rBRIEF: rotate by 90 degrees and match by descriptor alone.
  const OrbExtractor ex;
  const cv::Mat img = textured_image(3, 480, 480);
  ds3d::PinholeCamera cam;
  cam.width = 480;
  cam.height = 480;
  cv::Mat rot;
  cv::rotate(img, rot, cv::ROTATE_90_CLOCKWISE);
  const auto a = ex.extract(img, {}, cam);
  const auto b = ex.extract(rot, {}, cam);
  int good = 0;
  int tried = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a.keypoints[i].octave != 0) continue;
    ++tried;
    int best = 257;
    std::size_t bj = 0;
    for (std::size_t j = 0; j < b.size(); ++j) {
      const int d =
          ds3d::slam::descriptor_distance(a.descriptors.ptr<std::uint8_t>(static_cast<int>(i)),
                                          b.descriptors.ptr<std::uint8_t>(static_cast<int>(j)));
      if (d < best) {
        best = d;
        bj = j;
      }
    }
    // Clockwise rotation maps (x, y) to (h - 1 - y, x).
    const cv::Point2f expect(479.0F - a.keypoints[i].pt.y, a.keypoints[i].pt.x);
    if (best < 50 && cv::norm(b.keypoints[bj].pt - expect) < 3.0) ++good;
  }
  ASSERT_GT(tried, 100);
  EXPECT_GT(good, tried / 3);
}

TEST(OrbExtractor, AttachesDepthAndUndistorts) {
  const OrbExtractor ex;
  ds3d::PinholeCamera cam = plain_camera();
  cam.k1 = 0.2;
  cam.k2 = -0.5;
  cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(10000));  // 2 m
  depth(cv::Rect(0, 0, 320, 480)).setTo(0);              // left half missing
  depth(cv::Rect(320, 0, 160, 480)).setTo(60000);        // 12 m: beyond max_range
  depth(cv::Rect(480, 0, 80, 480)).setTo(25000);         // 5 m: far, but measured
  const auto f = ex.extract(textured_image(4), depth, cam);
  ASSERT_GT(f.size(), 500U);
  for (std::size_t i = 0; i < f.size(); ++i) {
    const auto& k = f.keypoints[i];
    const int x = static_cast<int>(std::lround(k.pt.x));
    if (x < 480) {
      EXPECT_EQ(f.depth[i], 0.0F);
      EXPECT_FALSE(f.has_depth(i));
    } else if (x < 560) {
      EXPECT_FLOAT_EQ(f.depth[i], 5.0F);
      EXPECT_FALSE(f.is_close(i));
    } else {
      EXPECT_FLOAT_EQ(f.depth[i], 2.0F);
      EXPECT_TRUE(f.is_close(i));
    }
    // Re-distorting the undistorted pixel gives back the raw keypoint.
    const Eigen::Vector2d xn((f.undistorted[i].x() - cam.cx) / cam.fx,
                             (f.undistorted[i].y() - cam.cy) / cam.fy);
    const Eigen::Vector2d xd = cam.distort(xn);
    EXPECT_NEAR(cam.fx * xd.x() + cam.cx, k.pt.x, 0.05);
    EXPECT_NEAR(cam.fy * xd.y() + cam.cy, k.pt.y, 0.05);
  }
}

TEST(OrbExtractor, BlackAndFlatImagesGiveNoFeatures) {
  const OrbExtractor ex;
  const auto f = ex.extract(cv::Mat::zeros(480, 640, CV_8UC3), {}, plain_camera());
  EXPECT_EQ(f.size(), 0U);
  EXPECT_TRUE(f.depth.empty());
  const auto g = ex.extract(cv::Mat(480, 640, CV_8UC1, cv::Scalar(200)), {}, plain_camera());
  EXPECT_EQ(g.size(), 0U);
}

TEST(OrbExtractor, RejectsBadInput) {
  const OrbExtractor ex;
  const auto cam = plain_camera();
  EXPECT_THROW((void)ex.extract(cv::Mat::zeros(480, 640, CV_32FC1), {}, cam),
               ds3d::InvalidArgument);
  EXPECT_THROW((void)ex.extract(cv::Mat::zeros(240, 320, CV_8UC3), {}, cam), ds3d::InvalidArgument);
  EXPECT_THROW(
      (void)ex.extract(cv::Mat::zeros(480, 640, CV_8UC3), cv::Mat::zeros(480, 640, CV_32FC1), cam),
      ds3d::InvalidArgument);
  EXPECT_THROW(
      (void)ex.extract(cv::Mat::zeros(480, 640, CV_8UC3), cv::Mat::zeros(240, 640, CV_16UC1), cam),
      ds3d::InvalidArgument);
  OrbParams p;
  p.num_features = 0;
  EXPECT_THROW(OrbExtractor{p}, ds3d::InvalidArgument);
  p = {};
  p.scale_factor = 1.0;
  EXPECT_THROW(OrbExtractor{p}, ds3d::InvalidArgument);
  p = {};
  p.min_fast_threshold = 30;
  EXPECT_THROW(OrbExtractor{p}, ds3d::InvalidArgument);
  p = {};
  p.min_depth = 5.0;
  EXPECT_THROW(OrbExtractor{p}, ds3d::InvalidArgument);
  p = {};
  p.max_range = 1.0;
  EXPECT_THROW(OrbExtractor{p}, ds3d::InvalidArgument);
}

TEST(DescriptorDistance, CountsDifferingBits) {
  std::array<std::uint8_t, 32> a{};
  std::array<std::uint8_t, 32> b{};
  EXPECT_EQ(ds3d::slam::descriptor_distance(a.data(), b.data()), 0);
  b.fill(0xFF);
  EXPECT_EQ(ds3d::slam::descriptor_distance(a.data(), b.data()), 256);
  b.fill(0);
  b[31] = 0x81;
  EXPECT_EQ(ds3d::slam::descriptor_distance(a.data(), b.data()), 2);
}

}  // namespace

namespace {

// The spare candidates leave the primary features unchanged, are new keypoints, and describe()
// gives them the descriptors extract() would.
TEST(OrbExtractor, SpareCandidatesAreExtraAndDescribable) {
  const OrbExtractor ex;
  const cv::Mat img = textured_image(3);
  const auto plain = ex.extract(img, {}, plain_camera());
  ds3d::slam::OrbFeatures spare;
  const auto with = ex.extract(img, {}, plain_camera(), spare, 800);
  ASSERT_EQ(with.size(), plain.size());
  EXPECT_EQ(cv::norm(with.descriptors, plain.descriptors, cv::NORM_HAMMING), 0.0);
  EXPECT_GT(spare.size(), 400U);
  EXPECT_LE(spare.size(), 808U);  // per-level shares are rounded
  EXPECT_TRUE(spare.descriptors.empty());
  for (const auto& s : spare.keypoints) {
    for (const auto& k : plain.keypoints) {
      ASSERT_FALSE(s.octave == k.octave && s.pt == k.pt) << "spare candidate repeats a feature";
    }
  }
  const auto described = ex.describe(img, plain.keypoints, {}, plain_camera());
  EXPECT_EQ(cv::norm(described.descriptors, plain.descriptors, cv::NORM_HAMMING), 0.0);
  EXPECT_THROW((void)ex.extract(img, {}, plain_camera(), spare, -1), ds3d::InvalidArgument);
}

}  // namespace

namespace {

void expect_same_features(const ds3d::slam::OrbFeatures& a, const ds3d::slam::OrbFeatures& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    const cv::KeyPoint& x = a.keypoints[i];
    const cv::KeyPoint& y = b.keypoints[i];
    ASSERT_TRUE(x.pt == y.pt && x.angle == y.angle && x.size == y.size && x.octave == y.octave &&
                x.response == y.response && x.class_id == y.class_id)
        << "keypoint " << i;
  }
  ASSERT_EQ(a.descriptors.size(), b.descriptors.size());
  ASSERT_EQ(a.descriptors.type(), b.descriptors.type());
  if (!a.descriptors.empty()) {
    EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_HAMMING), 0.0);
  }
  EXPECT_EQ(a.undistorted, b.undistorted);
  EXPECT_EQ(a.depth, b.depth);
  EXPECT_EQ(a.close_depth, b.close_depth);
}

// Depth with holes and a range of 0.05-12 m, so that min_depth, max_depth and max_range matter.
cv::Mat ramp_depth(int w = 640, int h = 480) {
  cv::Mat d(h, w, CV_16UC1);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      d.at<std::uint16_t>(y, x) =
          (x / 7 + y / 5) % 13 == 0 ? 0 : static_cast<std::uint16_t>(250 + 60 * x + 7 * y);
    }
  }
  return d;
}

// An extractor with fewer features, another depth range or distortion gets from the recorded
// corners exactly what it would extract itself; one with another pyramid, a larger budget or
// another image size gets nothing.
TEST(OrbExtractor, ExtractFromRecordedCornersEqualsExtract) {
  const cv::Mat img = textured_image(5);
  const cv::Mat depth = ramp_depth();
  ds3d::PinholeCamera cam = plain_camera();
  cam.k1 = 0.05;
  const OrbExtractor front;
  ds3d::slam::OrbCorners corners;
  ds3d::slam::OrbFeatures spare;
  const auto mine = front.extract(img, depth, cam, spare, 300, corners);
  ASSERT_EQ(corners.cells.size(), 8U);
  ASSERT_EQ(corners.picked.size(), mine.size());
  for (const int n : {1000, 800, 250}) {
    for (const double max_depth : {3.0, 6.0}) {
      OrbParams p;
      p.num_features = n;
      p.max_depth = max_depth;
      p.max_range = std::max(p.max_range, max_depth);
      const OrbExtractor other(p);
      const auto shared = other.extract_from(corners, depth, cam);
      ASSERT_TRUE(shared.has_value()) << n << " features, max_depth " << max_depth;
      expect_same_features(*shared, other.extract(img, depth, cam));
      expect_same_features(*other.extract_from(corners, {}, cam), other.extract(img, {}, cam));
    }
  }
  OrbParams p;
  p.num_features = 2000;  // more per level than was described
  EXPECT_FALSE(OrbExtractor(p).extract_from(corners, depth, cam).has_value());
  p = {};
  p.fast_threshold = 25;
  EXPECT_FALSE(OrbExtractor(p).extract_from(corners, depth, cam).has_value());
  p = {};
  p.num_levels = 6;
  EXPECT_FALSE(OrbExtractor(p).extract_from(corners, depth, cam).has_value());
  ds3d::PinholeCamera small = cam;
  small.width = 320;
  small.height = 240;
  EXPECT_FALSE(front.extract_from(corners, {}, small).has_value());
  EXPECT_THROW((void)front.extract_from(corners, cv::Mat::zeros(240, 640, CV_16UC1), cam),
               ds3d::InvalidArgument);
  // A black image: no corners, no features, and the same empty result.
  ds3d::slam::OrbCorners none;
  const auto empty = front.extract(cv::Mat::zeros(480, 640, CV_8UC3), {}, cam, spare, 0, none);
  expect_same_features(*front.extract_from(none, {}, cam), empty);
}

}  // namespace
