// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// disparity_inv_sigma2: how much the depth measured at each keypoint can be trusted, as the
// information 1/σ_d² of its disparity bf/z (FrontendConfig::disparity_sigma). The sensor's own
// σ (constant in disparity for a Kinect-like σ_z ∝ z²) plus the disparity spread of the depth
// around the keypoint: a corner on an occluding contour, or next to a hole, takes its depth from
// whichever side its pixel falls on, and that depth says little about the 3-D point.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "slam_frontend_impl.hpp"

namespace ds3d::slam {
namespace {

// Ring of 8 directions, radius 2 px at level 0 (scaled by the level): about where a keypoint of
// that level may lie.
constexpr std::array<std::array<float, 2>, 8> kRing{{{2, 0},
                                                     {1.41F, 1.41F},
                                                     {0, 2},
                                                     {-1.41F, 1.41F},
                                                     {-2, 0},
                                                     {-1.41F, -1.41F},
                                                     {0, -2},
                                                     {1.41F, -1.41F}}};

// Largest |bf/z_n − bf/z| over the ring around `pt` [px]; bf/z itself when a ring pixel has no
// valid depth (the keypoint borders a hole) or lies outside the image.
double disparity_spread(const cv::Mat& depth, const cv::Point2f& pt, double scale, double z,
                        double bf, double depth_scale, const OrbParams& orb) {
  const double d = bf / z;
  double spread = 0;
  for (const auto& o : kRing) {
    const int x = static_cast<int>(std::lround(pt.x + o[0] * scale));
    const int y = static_cast<int>(std::lround(pt.y + o[1] * scale));
    if (x < 0 || y < 0 || x >= depth.cols || y >= depth.rows) return d;
    const double zn = depth.at<std::uint16_t>(y, x) / depth_scale;
    if (zn < orb.min_depth || zn > orb.max_range) return d;
    spread = std::max(spread, std::abs(bf / zn - d));
  }
  return spread;
}

}  // namespace

std::vector<float> disparity_inv_sigma2(const PreparedFrame& pf, const FrontendConfig& cfg,
                                        const OrbExtractor& extractor) {
  const auto& feat = pf.features;
  std::vector<float> out(feat.size(), 0.0F);
  const cv::Mat& depth = pf.input.depth;
  if (cfg.disparity_sigma <= 0 || depth.empty()) return out;
  const double s0 = cfg.disparity_sigma * cfg.disparity_sigma;
  for (std::size_t i = 0; i < feat.size(); ++i) {
    if (!feat.has_depth(i)) continue;
    const cv::KeyPoint& k = feat.keypoints[i];
    const double spread = disparity_spread(depth, k.pt, extractor.level_scale(k.octave),
                                           feat.depth[i], cfg.bf, cfg.camera.depth_scale, cfg.orb);
    out[i] = static_cast<float>(1.0 / (s0 + spread * spread));
  }
  return out;
}

}  // namespace ds3d::slam
