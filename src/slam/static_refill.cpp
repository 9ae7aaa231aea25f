// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// refill_static: spare ORB candidates in place of the keypoints the dynamic filter removed.
#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>

#include "ds3d/slam/dynamic/boxes.hpp"
#include "slam_frontend_impl.hpp"

namespace ds3d::slam {
namespace {

constexpr float kBin = 32.0F;  // [px] bucket edge of the removed keypoints' lookup grid

// Removed keypoints bucketed on a coarse grid: "is one within r of p?" in O(r² / kBin²).
class RemovedGrid {
 public:
  RemovedGrid(const PreparedFrame& pf, int width, int height)
      : cols_(static_cast<int>(std::ceil(static_cast<float>(width) / kBin))),
        rows_(static_cast<int>(std::ceil(static_cast<float>(height) / kBin))),
        bins_(static_cast<std::size_t>(cols_ * rows_)) {
    for (std::size_t i = 0; i < pf.features.size(); ++i) {
      if (pf.dynamic[i] == 0U) continue;
      const cv::Point2f& p = pf.features.keypoints[i].pt;
      bins_[index(bin(p.x, cols_), bin(p.y, rows_))].push_back(p);
    }
  }
  [[nodiscard]] bool near(const cv::Point2f& p, float r) const {
    const int c0 = bin(p.x - r, cols_);
    const int c1 = bin(p.x + r, cols_);
    const int r0 = bin(p.y - r, rows_);
    const int r1 = bin(p.y + r, rows_);
    for (int y = r0; y <= r1; ++y) {
      for (int x = c0; x <= c1; ++x) {
        for (const cv::Point2f& q : bins_[index(x, y)]) {
          const cv::Point2f d = q - p;
          if (d.dot(d) <= r * r) return true;
        }
      }
    }
    return false;
  }

 private:
  static int bin(float v, int n) {
    return std::clamp(static_cast<int>(std::floor(v / kBin)), 0, n - 1);
  }
  [[nodiscard]] std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y * cols_ + x);
  }
  int cols_;
  int rows_;
  std::vector<std::vector<cv::Point2f>> bins_;
};

}  // namespace

void refill_static(PreparedFrame& pf, const PinholeCamera& camera, const OrbExtractor& extractor) {
  const std::vector<cv::KeyPoint> spare = std::move(pf.spare.keypoints);
  pf.spare = OrbFeatures{};
  pf.num_refilled = 0;
  const auto removed = static_cast<std::size_t>(
      std::count_if(pf.dynamic.begin(), pf.dynamic.end(), [](std::uint8_t d) { return d != 0U; }));
  if (removed == 0 || spare.empty()) return;
  const std::vector<ImageBox> boxes = image_boxes(pf.objects, camera);
  const RemovedGrid grid(pf, camera.width, camera.height);
  const auto cell = static_cast<float>(extractor.params().cell_size);
  std::vector<cv::KeyPoint> chosen;
  for (std::size_t j = 0; j < spare.size() && chosen.size() < removed; ++j) {
    const cv::KeyPoint& k = spare[j];
    const auto r = static_cast<float>(cell * extractor.level_scale(k.octave));
    if (in_mask(pf.objects.pixel_mask, k.pt) || in_any_box(boxes, k.pt) || grid.near(k.pt, r)) {
      continue;
    }
    chosen.push_back(k);
  }
  if (chosen.empty()) return;
  const OrbFeatures add =
      extractor.describe(pf.input.rgb, std::move(chosen), pf.input.depth, camera);
  OrbFeatures& f = pf.features;
  f.keypoints.insert(f.keypoints.end(), add.keypoints.begin(), add.keypoints.end());
  f.undistorted.insert(f.undistorted.end(), add.undistorted.begin(), add.undistorted.end());
  f.depth.insert(f.depth.end(), add.depth.begin(), add.depth.end());
  if (f.descriptors.empty()) {
    f.descriptors = add.descriptors.clone();
  } else {
    cv::vconcat(f.descriptors, add.descriptors, f.descriptors);
  }
  pf.dynamic.resize(f.keypoints.size(), 0);
  pf.num_refilled = static_cast<int>(add.keypoints.size());
}

}  // namespace ds3d::slam
