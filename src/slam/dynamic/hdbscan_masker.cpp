// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HdbscanMasker: the filter, the segmentation check and the pixel mask.
#include "ds3d/slam/dynamic/hdbscan_masker.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <optional>

#include "ds3d/detail/kdtree.hpp"
#include "ds3d/errors.hpp"
#include "dynamic_impl.hpp"

namespace ds3d::slam {

using impl::camera_image;
using impl::finite_rows_of;

namespace {

// A valid depth pixel of a window.
struct DepthPixel {
  std::uint16_t raw;
  int x;
  int y;
};

// The depth [m] a keypoint at pixel (x, y) without depth is given: the median of the valid depths
// in the (2 half + 1)² window, or, when those split at a gap of HdbscanMasker::kHoleDepthGap or
// more (a hole at a depth discontinuity: the silhouette of a person in front of what it hides),
// the median of the side whose colour matches the keypoint's pixel best, each side's colour
// being the mean of its pixels nearest to (x, y) (Chebyshev rings r and r + 1). Without a
// colour image of the depth's size (CV_8UC3) the median of the whole window. nullopt when the
// window holds no depth.
std::optional<double> hole_depth(const cv::Mat& depth, const cv::Mat& rgb, int x, int y, int half,
                                 double depth_scale) {
  std::vector<DepthPixel> w;
  for (int yy = std::max(0, y - half); yy <= std::min(depth.rows - 1, y + half); ++yy) {
    const auto* row = depth.ptr<std::uint16_t>(yy);
    for (int xx = std::max(0, x - half); xx <= std::min(depth.cols - 1, x + half); ++xx) {
      if (row[xx] != 0U) w.push_back({row[xx], xx, yy});
    }
  }
  if (w.empty()) return std::nullopt;
  std::sort(w.begin(), w.end(), [](const DepthPixel& a, const DepthPixel& b) {
    return a.raw < b.raw || (a.raw == b.raw && (a.y < b.y || (a.y == b.y && a.x < b.x)));
  });
  const auto median = [&](std::size_t a, std::size_t b) {
    return static_cast<double>(w[a + (b - a) / 2].raw) / depth_scale;
  };
  std::size_t cut = 0;  // near side [0, cut), far side [cut, n)
  int gap = 0;
  for (std::size_t k = 1; k < w.size(); ++k) {
    const int g = static_cast<int>(w[k].raw) - static_cast<int>(w[k - 1].raw);
    if (g > gap) {
      gap = g;
      cut = k;
    }
  }
  const bool colour = rgb.type() == CV_8UC3 && rgb.rows == depth.rows && rgb.cols == depth.cols;
  if (!colour || static_cast<double>(gap) / depth_scale < HdbscanMasker::kHoleDepthGap) {
    return median(0, w.size());
  }
  const cv::Vec3b& here = rgb.at<cv::Vec3b>(y, x);
  const auto ring = [&](const DepthPixel& p) {
    return std::max(std::abs(p.x - x), std::abs(p.y - y));
  };
  double colour_distance[2] = {0.0, 0.0};
  for (int side = 0; side < 2; ++side) {
    const std::size_t a = side == 0 ? 0 : cut;
    const std::size_t b = side == 0 ? cut : w.size();
    int nearest = std::numeric_limits<int>::max();
    for (std::size_t k = a; k < b; ++k) nearest = std::min(nearest, ring(w[k]));
    double sum[3] = {0.0, 0.0, 0.0};
    int n = 0;
    for (std::size_t k = a; k < b; ++k) {
      if (ring(w[k]) > nearest + 1) continue;
      const cv::Vec3b& c = rgb.at<cv::Vec3b>(w[k].y, w[k].x);
      for (int ch = 0; ch < 3; ++ch) sum[ch] += c[ch];
      ++n;
    }
    double d2 = 0.0;
    for (int ch = 0; ch < 3; ++ch) {
      const double diff = sum[ch] / n - static_cast<double>(here[ch]);
      d2 += diff * diff;
    }
    colour_distance[side] = d2;
  }
  return colour_distance[0] <= colour_distance[1] ? median(0, cut) : median(cut, w.size());
}

}  // namespace

HdbscanMasker::HdbscanMasker(const DynamicFilterParams& params) : filter_(params) {}

std::vector<std::uint8_t> HdbscanMasker::mask(const FrameInput& frame, const PinholeCamera& camera,
                                              const OrbFeatures& features,
                                              const DynamicObjects& objects) {
  const Keypoints3f kp = keypoint_array(features, frame.depth, camera);
  last_ = filter_.filter(kp, image_boxes(objects, camera), camera, objects.support_plane);
  std::vector<std::uint8_t> out = last_.dynamic;
  vetoed_ = 0;
  added_ = 0;
  confirm_foreground(frame, camera, kp, objects, out);
  const cv::Mat& m = objects.pixel_mask;
  if (camera_image(m, CV_8UC1, camera)) {
    for (std::size_t i = 0; i < features.size(); ++i) {
      const cv::Point2f& p = features.keypoints[i].pt;
      const int x = std::clamp(static_cast<int>(std::lround(p.x)), 0, camera.width - 1);
      const int y = std::clamp(static_cast<int>(std::lround(p.y)), 0, camera.height - 1);
      if (m.at<std::uint8_t>(y, x) != 0U) out[i] = 1;
    }
  }
  return out;
}

void HdbscanMasker::confirm_foreground(const FrameInput& frame, const PinholeCamera& camera,
                                       const Keypoints3f& kp, const DynamicObjects& objects,
                                       std::vector<std::uint8_t>& out) {
  const Segmentation& sg = objects.segmentation;
  const auto& seg = sg.boxes_3d_segmented;
  if (std::none_of(seg.begin(), seg.end(), [](std::uint8_t f) { return f != 0U; })) return;
  DS3D_CHECK(seg.size() == objects.boxes_3d.size(),
             "ds3d::slam::HdbscanMasker::mask: objects.boxes_3d_segmented must be empty or hold "
             "one flag per 3-D box (got ",
             seg.size(), " flags for ", objects.boxes_3d.size(), " boxes)");
  DS3D_CHECK(std::isfinite(sg.foreground_radius) && sg.foreground_radius > 0.0F,
             "ds3d::slam::HdbscanMasker::mask: objects.foreground_radius must be finite and > 0 "
             "(got ",
             sg.foreground_radius, ")");
  // Image rectangles of the boxes without segmentation (their keypoints are not checked) and of
  // the segmented ones (where keypoints without depth are looked at).
  DynamicObjects plain;
  DynamicObjects segmented;
  plain.boxes_2d = objects.boxes_2d;
  plain.scores = objects.scores;
  for (std::size_t j = 0; j < objects.boxes_3d.size(); ++j) {
    DynamicObjects& to = seg[j] != 0U ? segmented : plain;
    to.boxes_3d.push_back(objects.boxes_3d[j]);
  }
  const std::vector<ImageBox> plain_rects = image_boxes(plain, camera);
  const std::vector<ImageBox> seg_rects = image_boxes(segmented, camera);
  const auto inside = [](const std::vector<ImageBox>& rects, float u, float v) {
    return std::any_of(rects.begin(), rects.end(),
                       [&](const ImageBox& b) { return b.contains(u, v); });
  };
  // Foreground points, and background points when the source gives them (nearest-neighbour
  // label transfer), in KD-trees.
  const std::vector<std::uint32_t> finite_rows = finite_rows_of(sg.foreground_points);
  const detail::KdTreeCloudAdaptor<Points3f> adaptor{sg.foreground_points, &finite_rows};
  detail::KdTree3f<Points3f> tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const std::vector<std::uint32_t> bg_rows = finite_rows_of(sg.background_points);
  const detail::KdTreeCloudAdaptor<Points3f> bg_adaptor{sg.background_points, &bg_rows};
  detail::KdTree3f<Points3f> bg_tree(3, bg_adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const double r2 =
      static_cast<double>(sg.foreground_radius) * static_cast<double>(sg.foreground_radius);
  // The foreground's bounding box grown by the radius: a point outside it has no foreground
  // point within the radius (most keypoints, once the whole frame is checked), no query needed.
  Eigen::Vector3f fg_lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  Eigen::Vector3f fg_hi = -fg_lo;
  for (const std::uint32_t r : finite_rows) {
    fg_lo = fg_lo.cwiseMin(sg.foreground_points.row(r).transpose());
    fg_hi = fg_hi.cwiseMax(sg.foreground_points.row(r).transpose());
  }
  fg_lo.array() -= sg.foreground_radius;
  fg_hi.array() += sg.foreground_radius;
  // On the plane the source removed before segmenting (no label there): off the segment. The
  // support-plane rule of the filter: support_margin plus 3σ of the depth noise along the normal.
  std::optional<Eigen::Vector4f> plane;
  if (sg.segment_plane) {
    plane = detail::unit_plane(*sg.segment_plane, "ds3d::slam::HdbscanMasker::mask",
                               "objects.segment_plane");
  }
  const DynamicFilterParams& fp = filter_.params();
  const auto on_plane = [&](const Eigen::Vector3f& q, double z) {
    const auto zf = static_cast<float>(z);
    return plane &&
           detail::near_plane(*plane, q, q / zf, fp.depth_noise * zf * zf, fp.support_margin);
  };
  const auto on_segment = [&](float u, float v, double z) {
    if (finite_rows.empty()) return false;
    const Eigen::Vector3f q = camera.back_project(u, v, z).cast<float>();
    if ((q.array() < fg_lo.array()).any() || (q.array() > fg_hi.array()).any()) return false;
    if (on_plane(q, z)) return false;
    std::uint32_t index = 0;
    double d2 = 0.0;
    tree.knnSearch(q.data(), 1, &index, &d2);
    if (d2 > r2) return false;
    if (bg_rows.empty()) return true;
    // Nearest-neighbour label transfer: the nearest segmented point must be a foreground one.
    double bg_d2 = 0.0;
    bg_tree.knnSearch(q.data(), 1, &index, &bg_d2);
    return d2 <= bg_d2;
  };
  const bool everywhere = sg.segment_outside_boxes;
  const cv::Mat& depth = frame.depth;
  const bool raw = camera_image(depth, CV_16UC1, camera);
  for (std::size_t i = 0; i < out.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    const float u = kp(r, 0);
    const float v = kp(r, 1);
    const float z = kp(r, 2);
    if (!std::isfinite(u) || !std::isfinite(v)) continue;
    if (std::isfinite(z) && z > 0.0F) {
      if (inside(plain_rects, u, v)) continue;
      if (out[i] == 0U) {
        // A keypoint the box's clustering kept static although it passed the box's gates (a
        // desk in front took the foreground cluster, the person split in depth), or with a
        // whole-frame segmentation any keypoint outside the unsegmented boxes (a body part
        // outside its box): the segmentation decides.
        const bool candidate = everywhere || (last_.gated[i] != 0U && inside(seg_rects, u, v));
        if (candidate && on_segment(u, v, z)) {
          out[i] = 1;
          ++added_;
        }
        continue;
      }
      if (!on_segment(u, v, z)) {
        out[i] = 0;
        ++vetoed_;
      }
      continue;
    }
    // No depth at the keypoint: checked inside segmented boxes' rectangles (everywhere with a
    // whole-frame segmentation), and where the filter made it dynamic outside them (a region
    // carried from the previous frame), like a dynamic keypoint with depth.
    if (inside(plain_rects, u, v) || (!everywhere && !inside(seg_rects, u, v) && out[i] == 0U)) {
      continue;
    }
    bool dynamic = false;
    if (raw) {
      const int x = std::clamp(static_cast<int>(std::lround(u)), 0, camera.width - 1);
      const int y = std::clamp(static_cast<int>(std::lround(v)), 0, camera.height - 1);
      const std::optional<double> zb =
          hole_depth(depth, frame.rgb, x, y, kForegroundWindow, camera.depth_scale);
      if (zb) dynamic = on_segment(u, v, *zb);
    }
    if (dynamic && out[i] == 0U) ++added_;
    if (!dynamic && out[i] != 0U) ++vetoed_;
    out[i] = dynamic ? 1 : 0;
  }
}

}  // namespace ds3d::slam
