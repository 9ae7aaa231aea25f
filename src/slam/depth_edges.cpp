// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// mark_depth_edges: keypoints on an occluding contour (a depth step inside their patch) at a
// dynamic region are removed from tracking and mapping. Such a corner is no fixed 3-D point:
// its image position follows the edge, and where a person forms the edge it moves with the
// person, although its depth (the background's) makes the dynamic filter call it static.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "slam_frontend_impl.hpp"

namespace ds3d::slam {
namespace {

// Sample offsets: two rings (radius 4 and 8 px at level 0) in 8 directions. The FAST ring has
// radius 3 and the descriptor patch radius 15: a step within half the patch changes the corner.
constexpr std::array<std::array<float, 2>, 16> kOffsets{{{4, 0},
                                                         {2.83F, 2.83F},
                                                         {0, 4},
                                                         {-2.83F, 2.83F},
                                                         {-4, 0},
                                                         {-2.83F, -2.83F},
                                                         {0, -4},
                                                         {2.83F, -2.83F},
                                                         {8, 0},
                                                         {5.66F, 5.66F},
                                                         {0, 8},
                                                         {-5.66F, 5.66F},
                                                         {-8, 0},
                                                         {-5.66F, -5.66F},
                                                         {0, -8},
                                                         {5.66F, -5.66F}}};

// The 17 sample pixels around `pt`: the keypoint's own and the rings, scaled by `scale`.
std::array<cv::Point2f, 17> samples(const cv::Point2f& pt, double scale) {
  std::array<cv::Point2f, 17> out;
  out[0] = pt;
  const auto s = static_cast<float>(scale);
  for (std::size_t k = 0; k < kOffsets.size(); ++k) {
    out[k + 1] = pt + cv::Point2f(kOffsets[k][0] * s, kOffsets[k][1] * s);
  }
  return out;
}

// Nearest and farthest valid depth [m] at `pts` (inf, 0 when none is valid).
std::array<double, 2> depth_span(const cv::Mat& depth, const std::array<cv::Point2f, 17>& pts,
                                 double depth_scale, const OrbParams& orb) {
  double lo = INFINITY;
  double hi = 0;
  for (const cv::Point2f& p : pts) {
    const int xi = static_cast<int>(std::lround(p.x));
    const int yi = static_cast<int>(std::lround(p.y));
    if (xi < 0 || yi < 0 || xi >= depth.cols || yi >= depth.rows) continue;
    const double z = depth.at<std::uint16_t>(yi, xi) / depth_scale;
    if (z < orb.min_depth || z > orb.max_range) continue;
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  return {lo, hi};
}

}  // namespace

int mark_depth_edges(PreparedFrame& pf, const PinholeCamera& camera, const OrbExtractor& extractor,
                     double ratio) {
  const cv::Mat& depth = pf.input.depth;
  if (ratio <= 0 || depth.empty()) return 0;
  const std::vector<ImageBox> boxes = image_boxes(pf.objects, camera);
  const cv::Mat& mask = pf.objects.pixel_mask;
  if (boxes.empty() && mask.empty()) return 0;
  const std::size_t n = pf.features.size();
  int marked = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (pf.dynamic[i] != 0) continue;
    const cv::KeyPoint& k = pf.features.keypoints[i];
    const auto pts = samples(k.pt, extractor.level_scale(k.octave));
    const bool touches = std::any_of(pts.begin(), pts.end(), [&](const cv::Point2f& p) {
      return in_any_box(boxes, p) || in_mask(mask, p);
    });
    if (!touches) continue;
    const auto [lo, hi] = depth_span(depth, pts, camera.depth_scale, extractor.params());
    if (hi > (1.0 + ratio) * lo) {
      pf.dynamic[i] = kDepthEdgeFlag;
      ++marked;
    }
  }
  return marked;
}

}  // namespace ds3d::slam
