// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/dynamic/dynamic_sources.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>
#include <system_error>
#include <utility>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "ds3d/detail/kdtree.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/slam/dynamic/geometric_motion.hpp"

namespace ds3d::slam {

namespace {

// True when `m` is a non-empty image of `type` and of the camera's size.
bool camera_image(const cv::Mat& m, int type, const PinholeCamera& camera) {
  return !m.empty() && m.type() == type && m.cols == camera.width && m.rows == camera.height;
}

}  // namespace

void FileSourceParams::validate() const {
  DS3D_CHECK(std::isfinite(max_dt) && max_dt >= 0.0,
             "ds3d::slam::FileSourceParams: max_dt must be >= 0 (got ", max_dt, ")");
  DS3D_CHECK(std::isfinite(min_score) && min_score >= 0.0F && min_score <= 1.0F,
             "ds3d::slam::FileSourceParams: min_score must be in [0, 1] (got ", min_score, ")");
}

FileSource::FileSource(const std::filesystem::path& path, FileSourceParams params)
    : FileSource(DetectionsFile::read(path), std::move(params)) {}

FileSource::FileSource(DetectionsFile detections, FileSourceParams params)
    : file_(std::move(detections)), params_(std::move(params)) {
  params_.validate();
}

DynamicObjects FileSource::detect(const FrameInput& frame, const PinholeCamera& /*camera*/) {
  DynamicObjects out;
  const DetectionFrame* f = file_.find(frame.timestamp, params_.max_dt);
  if (f == nullptr) {
    ++unmatched_;
    return out;
  }
  ++matched_;
  for (const Detection& d : f->detections) {
    if (d.score < params_.min_score) continue;
    if (!params_.classes.empty() &&
        std::find(params_.classes.begin(), params_.classes.end(), d.cls) == params_.classes.end()) {
      continue;
    }
    if (d.is_3d) {
      out.boxes_3d.push_back(d.corners);
    } else {
      out.boxes_2d.emplace_back(d.box.x_min, d.box.y_min, d.box.width(), d.box.height());
      out.scores.push_back(d.score);
    }
  }
  return out;
}

std::vector<ImageBox> image_boxes(const DynamicObjects& objects, const PinholeCamera& camera) {
  DS3D_CHECK(objects.scores.empty() || objects.scores.size() == objects.boxes_2d.size(),
             "ds3d::slam::image_boxes: scores must be empty or one per 2-D box (got ",
             objects.scores.size(), " scores for ", objects.boxes_2d.size(), " boxes)");
  std::vector<ImageBox> out;
  for (std::size_t i = 0; i < objects.boxes_2d.size(); ++i) {
    const cv::Rect2f& r = objects.boxes_2d[i];
    ImageBox b;
    b.x_min = r.x;
    b.y_min = r.y;
    b.x_max = r.x + r.width;
    b.y_max = r.y + r.height;
    b.score = objects.scores.empty() ? 1.0F : objects.scores[i];
    // Clip to the image here so that boxes wholly outside are left out, as documented.
    b.x_max = std::min(b.x_max, static_cast<float>(camera.width) - 0.5F);
    b.y_max = std::min(b.y_max, static_cast<float>(camera.height) - 0.5F);
    b.x_min = std::max(b.x_min, -0.5F);
    b.y_min = std::max(b.y_min, -0.5F);
    if (b.x_max > b.x_min && b.y_max > b.y_min) out.push_back(b);
  }
  const auto& margins = objects.boxes_3d_margin;
  DS3D_CHECK(margins.empty() || margins.size() == objects.boxes_3d.size(),
             "ds3d::slam::image_boxes: boxes_3d_margin must be empty or one per 3-D box (got ",
             margins.size(), " margins for ", objects.boxes_3d.size(), " boxes)");
  for (std::size_t i = 0; i < margins.size(); ++i) {
    DS3D_CHECK(margins[i] >= 0.0F, "ds3d::slam::image_boxes: boxes_3d_margin[", i,
               "] must be >= 0 or +inf (got ", margins[i], ")");
  }
  for (std::size_t i = 0; i < objects.boxes_3d.size(); ++i) {
    const auto& c = objects.boxes_3d[i];
    if (!c.allFinite()) continue;
    auto b = project_box(c, camera);
    if (!b) continue;
    if (!margins.empty() && std::isfinite(margins[i])) b->solid = solid_from_corners(c, margins[i]);
    out.push_back(*b);
  }
  return out;
}

Keypoints3f keypoint_array(const OrbFeatures& features, const cv::Mat& depth,
                           const PinholeCamera& camera) {
  const bool raw = camera_image(depth, CV_16UC1, camera);
  Keypoints3f kp(static_cast<Eigen::Index>(features.size()), 3);
  for (std::size_t i = 0; i < features.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    const cv::Point2f& p = features.keypoints[i].pt;
    kp(r, 0) = p.x;
    kp(r, 1) = p.y;
    float z = features.depth[i];
    if (raw) {
      const int x = std::clamp(static_cast<int>(std::lround(p.x)), 0, camera.width - 1);
      const int y = std::clamp(static_cast<int>(std::lround(p.y)), 0, camera.height - 1);
      z = static_cast<float>(depth.at<std::uint16_t>(y, x) / camera.depth_scale);
    }
    kp(r, 2) = z;
  }
  return kp;
}

namespace {

// The finite rows of a point set (the KD-trees of the segmentation are built over them only).
std::vector<std::uint32_t> finite_rows_of(const Points3f& pts) {
  std::vector<std::uint32_t> rows;
  for (Eigen::Index r = 0; r < pts.rows(); ++r) {
    if (pts.row(r).allFinite()) rows.push_back(static_cast<std::uint32_t>(r));
  }
  return rows;
}

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
  const auto& seg = objects.boxes_3d_segmented;
  if (std::none_of(seg.begin(), seg.end(), [](std::uint8_t f) { return f != 0U; })) return;
  DS3D_CHECK(seg.size() == objects.boxes_3d.size(),
             "ds3d::slam::HdbscanMasker::mask: objects.boxes_3d_segmented must be empty or hold "
             "one flag per 3-D box (got ",
             seg.size(), " flags for ", objects.boxes_3d.size(), " boxes)");
  DS3D_CHECK(std::isfinite(objects.foreground_radius) && objects.foreground_radius > 0.0F,
             "ds3d::slam::HdbscanMasker::mask: objects.foreground_radius must be finite and > 0 "
             "(got ",
             objects.foreground_radius, ")");
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
  const std::vector<std::uint32_t> finite_rows = finite_rows_of(objects.foreground_points);
  const detail::KdTreeCloudAdaptor<Points3f> adaptor{objects.foreground_points, &finite_rows};
  detail::KdTree3f<Points3f> tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const std::vector<std::uint32_t> bg_rows = finite_rows_of(objects.background_points);
  const detail::KdTreeCloudAdaptor<Points3f> bg_adaptor{objects.background_points, &bg_rows};
  detail::KdTree3f<Points3f> bg_tree(3, bg_adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const double r2 = static_cast<double>(objects.foreground_radius) *
                    static_cast<double>(objects.foreground_radius);
  // The foreground's bounding box grown by the radius: a point outside it has no foreground
  // point within the radius (most keypoints, once the whole frame is checked), no query needed.
  Eigen::Vector3f fg_lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  Eigen::Vector3f fg_hi = -fg_lo;
  for (const std::uint32_t r : finite_rows) {
    fg_lo = fg_lo.cwiseMin(objects.foreground_points.row(r).transpose());
    fg_hi = fg_hi.cwiseMax(objects.foreground_points.row(r).transpose());
  }
  fg_lo.array() -= objects.foreground_radius;
  fg_hi.array() += objects.foreground_radius;
  // On the plane the source removed before segmenting (no label there): off the segment. The
  // support-plane rule of the filter: support_margin plus 3σ of the depth noise along the normal.
  std::optional<Eigen::Vector4f> plane;
  if (objects.segment_plane) {
    plane = detail::unit_plane(*objects.segment_plane, "ds3d::slam::HdbscanMasker::mask",
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
  const bool everywhere = objects.segment_outside_boxes;
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

// ---- HtxSource -------------------------------------------------------------------------------

void HtxSourceParams::validate() const {
  preprocess.validate();
  input.validate();
  DS3D_CHECK(std::isfinite(min_score) && min_score >= 0.0F && min_score <= 1.0F,
             "ds3d::slam::HtxSourceParams: min_score must be in [0, 1] (got ", min_score, ")");
  DS3D_CHECK(detect_every >= 1, "ds3d::slam::HtxSourceParams: detect_every must be >= 1 (got ",
             detect_every, ")");
  DS3D_CHECK(num_threads >= 0, "ds3d::slam::HtxSourceParams: num_threads must be >= 0 (got ",
             num_threads, ")");
  DS3D_CHECK(box_uncertainty >= 0.0F,
             "ds3d::slam::HtxSourceParams: box_uncertainty must be >= 0 or +inf (got ",
             box_uncertainty, ")");
  DS3D_CHECK(foreground_min_prob > 0.0F && foreground_min_prob < 1.0F,
             "ds3d::slam::HtxSourceParams: foreground_min_prob must be in (0, 1) (got ",
             foreground_min_prob, ")");
  DS3D_CHECK(std::isfinite(foreground_radius) && foreground_radius > 0.0F,
             "ds3d::slam::HtxSourceParams: foreground_radius must be finite and > 0 (got ",
             foreground_radius, ")");
  DS3D_CHECK(hold_frames >= 0, "ds3d::slam::HtxSourceParams: hold_frames must be >= 0 (got ",
             hold_frames, ")");
  DS3D_CHECK(hold_min_points >= 1,
             "ds3d::slam::HtxSourceParams: hold_min_points must be >= 1 (got ", hold_min_points,
             ")");
  DS3D_CHECK(draws >= 1, "ds3d::slam::HtxSourceParams: draws must be >= 1 (got ", draws, ")");
  DS3D_CHECK(segment_frames >= 0, "ds3d::slam::HtxSourceParams: segment_frames must be >= 0 (got ",
             segment_frames, ")");
  DS3D_CHECK(std::isfinite(segment_smoothing) && segment_smoothing >= 0.0F,
             "ds3d::slam::HtxSourceParams: segment_smoothing must be finite and >= 0 (got ",
             segment_smoothing, ")");
  DS3D_CHECK(std::isfinite(hold_seconds) && hold_seconds >= 0.0,
             "ds3d::slam::HtxSourceParams: hold_seconds must be finite and >= 0 (got ",
             hold_seconds, ")");
}

namespace {

std::vector<std::int32_t> class_labels(const std::vector<std::string>& wanted,
                                       const std::vector<std::string>& known) {
  std::vector<std::int32_t> out;
  for (const std::string& w : wanted) {
    const auto it = std::find(known.begin(), known.end(), w);
    if (it == known.end()) {
      std::ostringstream names;
      for (std::size_t i = 0; i < known.size(); ++i) names << (i > 0 ? ", " : "") << known[i];
      throw InvalidArgument(
          detail::concat("ds3d::slam::HtxSource: class '", w,
                         "' is not a class of the detector (classes: ", names.str(), ")"));
    }
    out.push_back(static_cast<std::int32_t>(it - known.begin()));
  }
  return out;
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Frame index mixed into the draw's seed (SplitMix64 finaliser), so consecutive frames get
// unrelated draws while the same frame always gets the same one.
std::uint64_t mix_seed(std::uint64_t seed, std::size_t index) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (static_cast<std::uint64_t>(index) + 1U);
  z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31U);
}

// Whether a box centred at `centre` continues `kept`, centred at `kept_centre` in the same frame:
// the centre lies within half kept's largest horizontal size (the detector reported the object
// again at about the same place; HtxSourceParams::hold_frames and draws).
bool continues(const Box3& kept, const Eigen::Vector3f& kept_centre,
               const Eigen::Vector3f& centre) {
  return (centre - kept_centre).norm() < 0.5F * std::max(kept.size.x(), kept.size.y());
}

}  // namespace

std::size_t keep_anchored_foreground(DynamicObjects& objects, float margin) {
  constexpr const char* kFn = "ds3d::slam::keep_anchored_foreground";
  DS3D_CHECK(margin >= 0.0F, kFn, ": margin must be >= 0 or +inf (got ", margin, ")");
  DS3D_CHECK(std::isfinite(objects.foreground_radius) && objects.foreground_radius > 0.0F, kFn,
             ": objects.foreground_radius must be finite and > 0 (got ", objects.foreground_radius,
             ")");
  Points3f& fg = objects.foreground_points;
  const std::vector<std::uint32_t> rows = finite_rows_of(fg);  // tree index -> row
  if (rows.empty()) return 0;
  // Seeds: the points inside a box's solid grown by the margin (tree indices).
  std::vector<std::uint8_t> anchored(rows.size(), 0);
  std::vector<std::uint32_t> queue;
  for (const Eigen::Matrix<float, 8, 3>& corners : objects.boxes_3d) {
    const std::optional<SolidBox> solid =
        solid_from_corners(corners, std::isfinite(margin) ? margin : 0.0F);
    if (!solid) continue;
    for (std::uint32_t t = 0; t < rows.size(); ++t) {
      const Eigen::Vector3f p = fg.row(rows[t]).transpose();
      if (anchored[t] != 0U || !(p.z() > 0.0F)) continue;
      if (solid->contains(p, p / p.z(), 0.0F)) {
        anchored[t] = 1;
        queue.push_back(t);
      }
    }
  }
  if (queue.size() < rows.size() && !queue.empty()) {
    // Breadth-first along the foreground: every point within the radius of an anchored one.
    const detail::KdTreeCloudAdaptor<Points3f> adaptor{fg, &rows};
    detail::KdTree3f<Points3f> tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree.buildIndex();
    const double r2 = static_cast<double>(objects.foreground_radius) * objects.foreground_radius;
    const auto reach = [&](std::uint32_t t) {  // never counted: the search visits them all
      if (anchored[t] == 0U) {
        anchored[t] = 1;
        queue.push_back(t);
      }
      return false;
    };
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const Eigen::Vector3f q = fg.row(rows[queue[head]]).transpose();
      detail::CountingRadiusResultSet<decltype(reach)> rs(r2, 1, reach);
      tree.findNeighbors(rs, q.data(), nanoflann::SearchParams());
    }
  }
  const std::size_t moved = rows.size() - queue.size();
  if (moved == 0) return 0;
  // Row order kept on both sides; non-finite rows stay with the foreground (ignored there).
  std::vector<std::uint8_t> stays(static_cast<std::size_t>(fg.rows()), 1);
  for (std::uint32_t t = 0; t < rows.size(); ++t) stays[rows[t]] = anchored[t];
  Points3f kept(fg.rows() - static_cast<Eigen::Index>(moved), 3);
  Points3f& bg = objects.background_points;
  Eigen::Index b = bg.rows();
  bg.conservativeResize(b + static_cast<Eigen::Index>(moved), 3);
  Eigen::Index a = 0;
  for (Eigen::Index r = 0; r < fg.rows(); ++r) {
    (stays[static_cast<std::size_t>(r)] != 0U ? kept.row(a++) : bg.row(b++)) = fg.row(r);
  }
  fg = std::move(kept);
  return moved;
}

std::vector<float> smooth_segmentation(const Points3f& points, const std::vector<float>& logits,
                                       double kernel_width, float weight, int iterations) {
  constexpr const char* kFn = "ds3d::slam::smooth_segmentation";
  DS3D_CHECK(logits.size() == static_cast<std::size_t>(points.rows()), kFn,
             ": logits must have one value per row of points (got ", logits.size(), " for ",
             points.rows(), " rows)");
  DS3D_CHECK(std::isfinite(kernel_width) && kernel_width > 0.0, kFn,
             ": kernel_width must be finite and > 0 (got ", kernel_width, ")");
  DS3D_CHECK(std::isfinite(weight) && weight >= 0.0F, kFn, ": weight must be finite and >= 0 (got ",
             weight, ")");
  DS3D_CHECK(iterations >= 1, kFn, ": iterations must be >= 1 (got ", iterations, ")");
  std::vector<float> out = logits;
  if (weight == 0.0F) return out;
  std::vector<std::uint32_t> rows;  // the rows taking part: finite point and logit
  for (Eigen::Index r = 0; r < points.rows(); ++r) {
    if (points.row(r).allFinite() && std::isfinite(logits[static_cast<std::size_t>(r)])) {
      rows.push_back(static_cast<std::uint32_t>(r));
    }
  }
  if (rows.size() < 2) return out;
  Points3f compact(static_cast<Eigen::Index>(rows.size()), 3);  // no indirection in the tree
  for (std::size_t t = 0; t < rows.size(); ++t) {
    compact.row(static_cast<Eigen::Index>(t)) = points.row(rows[t]);
  }
  const detail::KdTreeCloudAdaptor<Points3f> adaptor{compact, nullptr};
  detail::KdTree3f<Points3f> tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  tree.buildIndex();
  // Up to kSmoothingNeighbours nearest points within two kernel widths (tree indices) and their
  // kernel weights, in CSR form. (nanoflann visits a built tree in a fixed order, and the
  // neighbours come sorted by distance: the sums below are deterministic.)
  constexpr std::size_t kK = kSmoothingNeighbours + 1;  // the point itself comes first
  std::vector<std::uint32_t> begin;
  begin.reserve(rows.size() + 1);
  begin.push_back(0);
  std::vector<std::uint32_t> nb;
  std::vector<float> kw;
  nb.reserve(rows.size() * kSmoothingNeighbours);
  kw.reserve(rows.size() * kSmoothingNeighbours);
  std::array<std::uint32_t, kK> idx{};
  std::array<double, kK> d2{};
  const double w2 = kernel_width * kernel_width;
  for (std::uint32_t t = 0; t < rows.size(); ++t) {
    const Eigen::Vector3f q = points.row(rows[t]).transpose();
    const auto found =
        static_cast<std::size_t>(tree.knnSearch(q.data(), kK, idx.data(), d2.data()));
    for (std::size_t k = 0; k < found; ++k) {
      if (idx[k] == t || d2[k] > 4.0 * w2) continue;
      nb.push_back(idx[k]);
      kw.push_back(static_cast<float>(std::exp(-d2[k] / w2)));
    }
    begin.push_back(static_cast<std::uint32_t>(nb.size()));
  }
  const auto sigmoid = [](float x) { return 1.0F / (1.0F + std::exp(-x)); };
  std::vector<float> q(rows.size());
  for (std::size_t t = 0; t < rows.size(); ++t) q[t] = sigmoid(logits[rows[t]]);
  std::vector<float> post(rows.size());
  for (int it = 0; it < iterations; ++it) {
    for (std::size_t t = 0; t < rows.size(); ++t) {
      float msg = 0.0F;
      for (std::uint32_t k = begin[t]; k < begin[t + 1]; ++k) {
        msg += kw[k] * (2.0F * q[nb[k]] - 1.0F);
      }
      post[t] = logits[rows[t]] + weight * msg;
    }
    for (std::size_t t = 0; t < rows.size(); ++t) q[t] = sigmoid(post[t]);
  }
  for (std::size_t t = 0; t < rows.size(); ++t) out[rows[t]] = post[t];
  return out;
}

HtxSource::HtxSource(std::shared_ptr<const SparseDetector> detector, HtxSourceParams params)
    : params_(std::move(params)), R_up_cam_(upright_rotation(Eigen::Vector3d(0.0, -1.0, 0.0))) {
  DS3D_CHECK(detector != nullptr, "ds3d::slam::HtxSource: detector must not be null");
  params_.validate();
  labels_ = class_labels(params_.classes, detector->config().class_names);
  const int threads = params_.num_threads;
  run_ = [detector, threads](Eigen::Ref<const Points3f> xyz) {
    DetectOptions opt;
    opt.num_threads = threads;
    opt.part_logits = true;
    return detector->run(xyz, opt);
  };
  detect_ = [detector = std::move(detector), threads](Eigen::Ref<const Points3f> xyz) {
    return detector->detect(xyz, threads);
  };
}

HtxSource::HtxSource(DetectFn detect, std::vector<std::string> class_names, HtxSourceParams params)
    : detect_(std::move(detect)),
      params_(std::move(params)),
      R_up_cam_(upright_rotation(Eigen::Vector3d(0.0, -1.0, 0.0))) {
  DS3D_CHECK(static_cast<bool>(detect_), "ds3d::slam::HtxSource: detect must not be empty");
  params_.validate();
  labels_ = class_labels(params_.classes, class_names);
}

DynamicObjects HtxSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  const bool run_now = frame_count_ % static_cast<std::size_t>(params_.detect_every) == 0;
  ++frame_count_;
  stats_ = HtxFrameStats{};
  if (!run_now) return last_objects_;  // carried: the last detection's camera-frame boxes
  last_objects_ = DynamicObjects{};
  boxes_.clear();
  if (frame.depth.empty()) return last_objects_;
  DS3D_CHECK(frame.depth.type() == CV_16UC1 && frame.depth.cols == camera.width &&
                 frame.depth.rows == camera.height,
             "ds3d::slam::HtxSource::detect: depth must be CV_16UC1 of ", camera.width, "x",
             camera.height, " (got type ", frame.depth.type(), ", ", frame.depth.cols, "x",
             frame.depth.rows, ")");
  const auto t0 = std::chrono::steady_clock::now();
  PreprocessParams pp = params_.preprocess;
  pp.num_threads = params_.num_threads;
  // The per-pixel undistortion table is built once per camera, not per frame.
  if (pp.depth.undistort && pp.depth.rays == nullptr) pp.depth.rays = rays_.get(camera);
  const PreprocessResult pre =
      preprocess(frame.depth.ptr<std::uint16_t>(), frame.depth.cols, frame.depth.rows,
                 static_cast<std::ptrdiff_t>(frame.depth.step1()), camera, pp);
  stats_.num_points = static_cast<std::size_t>(pre.points.rows());
  if (pre.ground_found) {
    const Eigen::Vector3d up = pre.ground_plane.head<3>();
    // The preprocess prior keeps the floor normal within 30° of camera -y, so this holds;
    // checked anyway so that a custom prior cannot make upright_rotation throw mid-sequence.
    if (up.allFinite() && up.y() < 0.0 && std::isfinite(pre.ground_plane.w())) {
      R_up_cam_ = upright_rotation(up);
      stats_.ground_found = true;
      const Eigen::Vector4f ground = (pre.ground_plane / up.norm()).cast<float>();
      // The floor preprocess removed (camera frame): the segmentation below gives it no label.
      if (params_.segment && run_) last_objects_.segment_plane = ground;
      // This frame's floor: the masker keeps the keypoints on it static.
      if (params_.report_floor) last_objects_.support_plane = ground;
    }
  }
  DetectorInputParams ip = params_.input;
  ip.seed = mix_seed(params_.input.seed, frame.index);
  const DetectorInput in = make_detector_input(pre.points, R_up_cam_, ip);
  stats_.preprocess_ms = ms_since(t0);
  if (in.points.rows() == 0) return last_objects_;
  const auto t1 = std::chrono::steady_clock::now();
  std::vector<Box3> boxes;
  std::size_t first_draw_boxes = 0;  // boxes[first_draw_boxes...] come from later draws
  const bool segment = params_.segment && static_cast<bool>(run_);
  if (segment) {
    // Every draw's part logits, summed per preprocessed point (a point drawn twice counts
    // twice); the first draw's boxes, then the later draws' boxes that none kept continues.
    const Eigen::Index n = pre.points.rows();
    std::vector<float> sum(static_cast<std::size_t>(n), 0.0F);
    std::vector<int> count(static_cast<std::size_t>(n), 0);
    for (int draw = 0; draw < params_.draws; ++draw) {
      DetectorInput extra;
      if (draw > 0) {
        DetectorInputParams dp = ip;
        dp.seed = mix_seed(ip.seed, static_cast<std::size_t>(draw));
        extra = make_detector_input(pre.points, R_up_cam_, dp);
      }
      const DetectorInput& d = draw == 0 ? in : extra;
      DetectorOutput o = run_(d.points);
      for (Eigen::Index k = 0; k < o.part_logits.rows(); ++k) {
        const std::uint32_t row = d.rows[static_cast<std::size_t>(k)];
        sum[row] += o.part_logits(k, 0);
        ++count[row];
      }
      const std::size_t kept = boxes.size();
      for (Box3& b : o.boxes) {
        const bool continued =
            std::any_of(boxes.begin(), boxes.begin() + static_cast<std::ptrdiff_t>(kept),
                        [&](const Box3& k) { return continues(k, k.centre, b.centre); });
        if (draw == 0 || !continued) boxes.push_back(std::move(b));
      }
      if (draw == 0) first_draw_boxes = boxes.size();
    }
    std::vector<float> logit(static_cast<std::size_t>(n), 0.0F);
    for (std::size_t k = 0; k < logit.size(); ++k) {
      if (count[k] > 0) logit[k] = sum[k] / static_cast<float>(count[k]);
    }
    smooth_over_frames(pre.points, count, frame.timestamp, logit);
    if (params_.segment_smoothing > 0.0F) {
      // Over the drawn points only (points no draw took have no logit).
      std::vector<std::uint32_t> drawn;
      for (std::size_t k = 0; k < count.size(); ++k) {
        if (count[k] > 0) drawn.push_back(static_cast<std::uint32_t>(k));
      }
      Points3f pts(static_cast<Eigen::Index>(drawn.size()), 3);
      std::vector<float> lg(drawn.size());
      for (std::size_t k = 0; k < drawn.size(); ++k) {
        pts.row(static_cast<Eigen::Index>(k)) = pre.points.row(drawn[k]);
        lg[k] = logit[drawn[k]];
      }
      lg = smooth_segmentation(pts, lg, largest_leaf_edge(), params_.segment_smoothing);
      for (std::size_t k = 0; k < drawn.size(); ++k) logit[drawn[k]] = lg[k];
    }
    // Foreground: sigmoid(logit) > p  <=>  logit > log(p / (1 - p)). The first draw's points in
    // its order (a point drawn twice is kept twice: harmless), then those only later draws
    // took; points no draw took are left out.
    const double p = params_.foreground_min_prob;
    const auto min_logit = static_cast<float>(std::log(p / (1.0 - p)));
    std::vector<Eigen::Index> fg;
    std::vector<Eigen::Index> bg;
    std::vector<std::uint8_t> in_first(static_cast<std::size_t>(n), 0);
    const auto label = [&](Eigen::Index row) {
      (logit[static_cast<std::size_t>(row)] > min_logit ? fg : bg).push_back(row);
    };
    for (const std::uint32_t row : in.rows) {
      label(row);
      in_first[row] = 1;
    }
    for (Eigen::Index k = 0; k < n; ++k) {
      const auto kk = static_cast<std::size_t>(k);
      if (count[kk] > 0 && in_first[kk] == 0U) label(k);
    }
    const auto gather = [&](const std::vector<Eigen::Index>& rows, Points3f& to) {
      to.resize(static_cast<Eigen::Index>(rows.size()), 3);
      for (std::size_t k = 0; k < rows.size(); ++k) {
        to.row(static_cast<Eigen::Index>(k)) = pre.points.row(rows[k]);
      }
    };
    gather(fg, last_objects_.foreground_points);
    gather(bg, last_objects_.background_points);
    last_objects_.foreground_radius = params_.foreground_radius;
    last_objects_.segment_outside_boxes = params_.segment_outside_boxes;
    stats_.num_foreground = fg.size();
  } else {
    boxes = detect_(in.points);
  }
  stats_.detect_ms = ms_since(t1);
  stats_.detected = true;
  const auto report = [&](const Box3& b, const Eigen::Matrix3f& R_up_cam) {
    const Eigen::Matrix3d R_cam_up = R_up_cam.cast<double>().transpose();
    Eigen::Matrix<float, 8, 3> corners;
    const auto up_corners = box::corners(b);
    for (int k = 0; k < 8; ++k) {
      corners.row(k) =
          (R_cam_up * up_corners[static_cast<std::size_t>(k)]).cast<float>().transpose();
    }
    last_objects_.boxes_3d.push_back(corners);
    last_objects_.boxes_3d_margin.push_back(params_.box_uncertainty);
    if (segment) last_objects_.boxes_3d_segmented.push_back(1);
  };
  if (!segment) first_draw_boxes = boxes.size();
  for (std::size_t j = 0; j < boxes.size(); ++j) {
    const Box3& b = boxes[j];
    if (!(b.score >= params_.min_score)) continue;  // also drops a NaN score
    if (!labels_.empty() && std::find(labels_.begin(), labels_.end(), b.label) == labels_.end()) {
      continue;
    }
    if (!b.centre.allFinite() || !b.size.allFinite() || !std::isfinite(b.yaw)) continue;
    report(b, R_up_cam_);
    boxes_.push_back(b);
    if (j >= first_draw_boxes) ++stats_.num_draw_boxes;
  }
  stats_.num_boxes = boxes_.size();
  // Whole-frame segmentation: only the foreground connected to a reported box is trusted.
  const auto finish = [&]() -> const DynamicObjects& {
    if (segment && params_.segment_outside_boxes) {
      stats_.num_unanchored = keep_anchored_foreground(last_objects_, params_.box_uncertainty);
      stats_.num_foreground -= stats_.num_unanchored;
    }
    return last_objects_;
  };
  if (!segment || params_.hold_frames == 0) return finish();
  // Carry the held boxes that no box of this frame continues while the segmentation still sees
  // foreground in them; then hold this frame's boxes.
  const Points3f& fg = last_objects_.foreground_points;
  std::vector<HeldBox> held;
  for (const Box3& b : boxes_) {
    // A box without foreground support is not held (nothing to follow it by).
    const auto [centroid, count] = foreground_in(b, R_up_cam_, fg);
    if (count >= params_.hold_min_points) {
      held.push_back({b, R_up_cam_, centroid, frame.timestamp, 0});
    }
  }
  for (HeldBox h : held_) {
    const double dt = frame.timestamp - h.timestamp;
    if (h.age >= params_.hold_frames || !(dt >= 0.0 && dt <= params_.hold_seconds)) continue;
    // Continued: a box of this frame has its centre within half this box's largest horizontal
    // size (the detector reported the object again at about the same place). Other held boxes
    // are not merged: the boxes of a person from consecutive frames often each cover only a part
    // of them, and their union gates more of the person (the segmentation decides inside).
    const Eigen::Vector3f c_cam = h.R_up_cam.transpose() * h.box.centre;
    const bool continued = std::any_of(boxes_.begin(), boxes_.end(), [&](const Box3& b) {
      return continues(h.box, c_cam, R_up_cam_.transpose() * b.centre);
    });
    if (continued) continue;
    const auto [centroid, count] = foreground_in(h.box, h.R_up_cam, fg);
    if (count < params_.hold_min_points) continue;
    h.box.centre += h.R_up_cam * (centroid - h.fg_centroid);
    h.fg_centroid = centroid;
    ++h.age;
    report(h.box, h.R_up_cam);
    ++stats_.num_carried;
    held.push_back(h);
  }
  held_ = std::move(held);
  stats_.num_boxes += stats_.num_carried;
  return finish();
}

struct HtxSource::PastSegmentation {
  explicit PastSegmentation(Points3f pts, std::vector<float> lg, double t)
      : points(std::move(pts)),
        logit(std::move(lg)),
        timestamp(t),
        adaptor{points, nullptr},
        tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {}
  Points3f points;                               // camera frame [m], finite
  std::vector<float> logit;                      // per row of points
  double timestamp = 0;                          // [s]
  detail::KdTreeCloudAdaptor<Points3f> adaptor;  // the tree keeps a reference to it
  detail::KdTree3f<Points3f> tree;
};

double HtxSource::largest_leaf_edge() const {
  const auto& leaf = params_.preprocess.voxel.leaf_size;
  return std::max({leaf.dx, leaf.dy, leaf.dz});
}

void HtxSource::smooth_over_frames(const Points3f& points, const std::vector<int>& count,
                                   double timestamp, std::vector<float>& logit) {
  if (params_.segment_frames == 0) return;
  // Frames too old (or a timestamp going back: another sequence) leave the window.
  while (!past_.empty() && !(timestamp - past_.front()->timestamp >= 0.0 &&
                             timestamp - past_.front()->timestamp <= params_.hold_seconds)) {
    past_.pop_front();
  }
  const double r2 = std::pow(largest_leaf_edge(), 2);
  std::vector<std::uint32_t> rows;
  for (Eigen::Index r = 0; r < points.rows(); ++r) {
    if (count[static_cast<std::size_t>(r)] > 0 && points.row(r).allFinite()) {
      rows.push_back(static_cast<std::uint32_t>(r));
    }
  }
  Points3f kept(static_cast<Eigen::Index>(rows.size()), 3);
  std::vector<float> kept_logit(rows.size());
  std::vector<float> mean = logit;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const std::uint32_t r = rows[k];
    kept.row(static_cast<Eigen::Index>(k)) = points.row(r);
    kept_logit[k] = logit[r];
    float s = logit[r];
    int m = 1;
    const Eigen::Vector3f q = points.row(r).transpose();
    for (const auto& f : past_) {
      std::uint32_t index = 0;
      double d2 = 0.0;
      if (f->tree.knnSearch(q.data(), 1, &index, &d2) == 1 && d2 <= r2) {
        s += f->logit[index];
        ++m;
      }
    }
    mean[r] = s / static_cast<float>(m);
  }
  logit = std::move(mean);
  past_.push_back(
      std::make_shared<const PastSegmentation>(std::move(kept), std::move(kept_logit), timestamp));
  while (past_.size() > static_cast<std::size_t>(params_.segment_frames)) past_.pop_front();
}

std::pair<Eigen::Vector3f, int> HtxSource::foreground_in(const Box3& b, const Eigen::Matrix3f& R,
                                                         const Points3f& fg) const {
  const double grow = std::isfinite(params_.box_uncertainty) ? 2.0 * params_.box_uncertainty : 0.0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (Eigen::Index k = 0; k < fg.rows(); ++k) {
    const Eigen::Vector3f p = fg.row(k).transpose();
    if (!p.allFinite()) continue;
    if (box::contains(b, (R * p).cast<double>(), grow)) {
      sum += p.cast<double>();
      ++n;
    }
  }
  if (n == 0) return {Eigen::Vector3f::Zero(), 0};
  return {(sum / n).cast<float>(), n};
}

// ---- CompositeSource ---------------------------------------------------------------------------

namespace {

// One segmentation flag per 3-D box of `o` (0 where o gives none).
std::vector<std::uint8_t> segmented_flags(const DynamicObjects& o) {
  std::vector<std::uint8_t> f = o.boxes_3d_segmented;
  f.resize(o.boxes_3d.size(), 0);
  return f;
}

// Appends the rows of `from` to `to`.
void append_rows(Points3f& to, const Points3f& from) {
  const Eigen::Index n = to.rows();
  to.conservativeResize(n + from.rows(), 3);
  to.bottomRows(from.rows()) = from;
}

// Sets to.boxes_3d_segmented to `flags` (one per to.boxes_3d) and adds the foreground and
// background points of `from` when one of its boxes made it into `to` segmented; empty flags
// when none is set.
void merge_segmentation(DynamicObjects& to, std::vector<std::uint8_t> flags,
                        const DynamicObjects& from, bool from_used) {
  if (from_used && from.foreground_points.rows() > 0) {
    const Eigen::Index n = to.foreground_points.rows();
    to.foreground_radius =
        n == 0 ? from.foreground_radius : std::max(to.foreground_radius, from.foreground_radius);
    append_rows(to.foreground_points, from.foreground_points);
    append_rows(to.background_points, from.background_points);
    if (!to.segment_plane) to.segment_plane = from.segment_plane;
    to.segment_outside_boxes = to.segment_outside_boxes || from.segment_outside_boxes;
  }
  if (std::none_of(flags.begin(), flags.end(), [](std::uint8_t f) { return f != 0U; })) {
    flags.clear();
  }
  to.boxes_3d_segmented = std::move(flags);
}

}  // namespace

CompositeSource::CompositeSource(std::shared_ptr<DynamicObjectSource> first,
                                 std::shared_ptr<DynamicObjectSource> second)
    : first_(std::move(first)), second_(std::move(second)) {
  DS3D_CHECK(first_ != nullptr && second_ != nullptr,
             "ds3d::slam::CompositeSource: both sources must be non-null (got first ",
             first_ ? "set" : "null", ", second ", second_ ? "set" : "null", ")");
}

std::string CompositeSource::name() const { return first_->name() + "+" + second_->name(); }

DynamicObjects CompositeSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  DynamicObjects out = first_->detect(frame, camera);
  FrameInput rest = frame;
  const std::vector<ImageBox> boxes = image_boxes(out, camera);
  const cv::Mat& m = out.pixel_mask;
  const bool has_mask = camera_image(m, CV_8UC1, camera);
  if (!frame.depth.empty() && (!boxes.empty() || has_mask)) {
    rest.depth = frame.depth.clone();  // the caller's image is shared: never write into it
    const cv::Rect image(0, 0, rest.depth.cols, rest.depth.rows);
    for (const ImageBox& b : boxes) {
      const cv::Rect r(
          cv::Point(static_cast<int>(std::floor(b.x_min)), static_cast<int>(std::floor(b.y_min))),
          cv::Point(static_cast<int>(std::ceil(b.x_max)) + 1,
                    static_cast<int>(std::ceil(b.y_max)) + 1));
      rest.depth(r & image).setTo(0);
    }
    if (has_mask && m.size() == rest.depth.size()) rest.depth.setTo(0, m);
  }
  DynamicObjects more = second_->detect(rest, camera);
  if (out.scores.empty() && !more.scores.empty()) out.scores.assign(out.boxes_2d.size(), 1.0F);
  if (!out.scores.empty() && more.scores.empty()) more.scores.assign(more.boxes_2d.size(), 1.0F);
  out.boxes_2d.insert(out.boxes_2d.end(), more.boxes_2d.begin(), more.boxes_2d.end());
  out.scores.insert(out.scores.end(), more.scores.begin(), more.scores.end());
  if (!out.boxes_3d_margin.empty() || !more.boxes_3d_margin.empty()) {
    // One margin per 3-D box once either source gives them (+inf: rectangle and depth range).
    constexpr float kInf = std::numeric_limits<float>::infinity();
    out.boxes_3d_margin.resize(out.boxes_3d.size(), kInf);
    more.boxes_3d_margin.resize(more.boxes_3d.size(), kInf);
    out.boxes_3d_margin.insert(out.boxes_3d_margin.end(), more.boxes_3d_margin.begin(),
                               more.boxes_3d_margin.end());
  }
  std::vector<std::uint8_t> flags = segmented_flags(out);
  const std::vector<std::uint8_t> more_flags = segmented_flags(more);
  flags.insert(flags.end(), more_flags.begin(), more_flags.end());
  out.boxes_3d.insert(out.boxes_3d.end(), more.boxes_3d.begin(), more.boxes_3d.end());
  merge_segmentation(out, std::move(flags), more, true);
  if (!out.support_plane) out.support_plane = more.support_plane;
  if (out.pixel_mask.empty()) {
    out.pixel_mask = more.pixel_mask;
  } else if (!more.pixel_mask.empty() && more.pixel_mask.size() == out.pixel_mask.size() &&
             more.pixel_mask.type() == out.pixel_mask.type()) {
    cv::bitwise_or(out.pixel_mask, more.pixel_mask, out.pixel_mask);
  }
  return out;
}

// ---- MotionGatedSource -------------------------------------------------------------------------

void MotionGateParams::validate() const {
  DS3D_CHECK(std::isfinite(keypoint_chi2) && keypoint_chi2 > 0.0,
             "ds3d::slam::MotionGateParams: keypoint_chi2 must be > 0 (got ", keypoint_chi2, ")");
  DS3D_CHECK(std::isfinite(alpha) && alpha > 0.0 && alpha < 1.0,
             "ds3d::slam::MotionGateParams: alpha must be in (0, 1) (got ", alpha, ")");
  DS3D_CHECK(hold_frames >= 0, "ds3d::slam::MotionGateParams: hold_frames must be >= 0 (got ",
             hold_frames, ")");
  DS3D_CHECK(std::isfinite(max_speed) && max_speed >= 0.0,
             "ds3d::slam::MotionGateParams: max_speed must be >= 0 (got ", max_speed, ")");
}

MotionGatedSource::MotionGatedSource(std::shared_ptr<DynamicObjectSource> semantic,
                                     std::shared_ptr<DynamicObjectSource> motion,
                                     MotionGateParams params)
    : semantic_(std::move(semantic)), motion_(std::move(motion)), params_(params) {
  DS3D_CHECK(semantic_ != nullptr && motion_ != nullptr,
             "ds3d::slam::MotionGatedSource: both sources must be non-null (got semantic ",
             semantic_ ? "set" : "null", ", motion ", motion_ ? "set" : "null", ")");
  params_.validate();
}

std::string MotionGatedSource::name() const {
  return semantic_->name() + (params_.evidence ? "&&" : "&") + motion_->name();
}

namespace {

// P(X >= k) for X ~ Binomial(n, p), summed in log space from k up until the terms vanish.
double binomial_sf(std::size_t k, std::size_t n, double p) {
  if (k == 0) return 1.0;
  if (k > n) return 0.0;
  if (p <= 0.0) return 0.0;
  if (p >= 1.0) return 1.0;
  const double dn = static_cast<double>(n);
  const double lp = std::log(p);
  const double lq = std::log1p(-p);
  double sum = 0.0;
  for (std::size_t i = k; i <= n; ++i) {
    const double di = static_cast<double>(i);
    const double term = std::exp(std::lgamma(dn + 1.0) - std::lgamma(di + 1.0) -
                                 std::lgamma(dn - di + 1.0) + di * lp + (dn - di) * lq);
    sum += term;
    if (di > dn * p && term < 1e-17 * sum) break;  // past the mode, the rest is negligible
  }
  return std::min(1.0, sum);
}

// Whether pixel (u, v) with depth z lies in box `b`, close to how the masker gates it: inside its
// solid (grown by its margin and 3σ(z)) when it has one, else inside its rectangle and depth range
// ± 3σ(z). Unlike the masker (DynamicFeatureFilter), σ is taken at the point's depth rather than
// at the range's ends, and with a solid only a looser depth bound precedes the solid test (the
// masker also requires the depth range ± 3σ there).
// `p` is the pixel back-projected (camera frame), computed at most once per point by the caller.
bool in_box(const ImageBox& b, const PinholeCamera& camera, float u, float v, float z,
            float depth_noise, std::optional<Eigen::Vector3f>& p) {
  if (!b.contains(u, v) || !(z > 0.0F)) return false;
  const float sigma_z = depth_noise * z * z;
  if (b.solid) {
    // Quick reject by depth first: the grown solid reaches at most √3·(margin + 3σ(z)·|ray|)
    // beyond the corners' depth range (|ray| < 2 inside any real field of view).
    const float reach = std::sqrt(3.0F) * (b.solid->margin + 6.0F * sigma_z);
    if (b.has_depth_range() && (z < b.z_min - reach || z > b.z_max + reach)) return false;
    if (!p) p = camera.back_project(u, v, z).cast<float>();
    const Eigen::Vector3f ray(p->x() / z, p->y() / z, 1.0F);
    return b.solid->contains(*p, ray, sigma_z);
  }
  if (!b.has_depth_range()) return true;
  return z >= b.z_min - 3.0F * sigma_z && z <= b.z_max + 3.0F * sigma_z;
}

}  // namespace

DynamicObjects MotionGatedSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  const DynamicObjects sem = semantic_->detect(frame, camera);
  DynamicObjects out = motion_->detect(frame, camera);
  ++frame_count_;
  const std::size_t now = frame_count_;
  const std::vector<ImageBox> moving = image_boxes(out, camera);
  const cv::Mat& m = out.pixel_mask;
  const bool has_mask = camera_image(m, CV_8UC1, camera);
  const cv::Rect image(0, 0, camera.width, camera.height);
  // One semantic box (as the image box image_boxes() makes of it) against the motion evidence.
  const auto gate = [&](const ImageBox& b) {
    for (const ImageBox& q : moving) {
      if (b.x_max < q.x_min || q.x_max < b.x_min || b.y_max < q.y_min || q.y_max < b.y_min) {
        continue;
      }
      if (b.has_depth_range() && q.has_depth_range() && (b.z_max < q.z_min || q.z_max < b.z_min)) {
        continue;
      }
      return true;
    }
    if (!has_mask) return false;
    const cv::Rect r(
        cv::Point(static_cast<int>(std::floor(b.x_min)), static_cast<int>(std::floor(b.y_min))),
        cv::Point(static_cast<int>(std::ceil(b.x_max)) + 1,
                  static_cast<int>(std::ceil(b.y_max)) + 1));
    const cv::Rect ri = r & image;
    return ri.area() > 0 && cv::countNonZero(m(ri)) > 0;
  };
  last_semantic_ = sem.boxes_2d.size() + sem.boxes_3d.size();
  last_kept_ = 0;
  last_by_evidence_ = 0;
  last_by_track_ = 0;

  // The semantic boxes as image boxes (2-D first, then 3-D; an empty optional when wholly outside
  // the image or behind the camera).
  std::vector<std::optional<ImageBox>> boxes;
  for (const cv::Rect2f& r : sem.boxes_2d) {
    DynamicObjects one;
    one.boxes_2d.push_back(r);
    const std::vector<ImageBox> ib = image_boxes(one, camera);
    boxes.push_back(ib.empty() ? std::nullopt : std::optional<ImageBox>(ib.front()));
  }
  for (std::size_t i = 0; i < sem.boxes_3d.size(); ++i) {
    DynamicObjects one;
    one.boxes_3d.push_back(sem.boxes_3d[i]);
    if (!sem.boxes_3d_margin.empty()) one.boxes_3d_margin.push_back(sem.boxes_3d_margin[i]);
    const std::vector<ImageBox> ib = image_boxes(one, camera);
    boxes.push_back(ib.empty() ? std::nullopt : std::optional<ImageBox>(ib.front()));
  }
  std::vector<std::uint8_t> keep(boxes.size(), 0);
  for (std::size_t i = 0; i < boxes.size(); ++i) keep[i] = boxes[i] && gate(*boxes[i]) ? 1 : 0;

  const auto* geo = dynamic_cast<const GeometricMotionSource*>(motion_.get());
  if (params_.evidence && geo != nullptr && !boxes.empty()) {
    const float noise = geo->params().depth_noise;
    const bool raw_depth = camera_image(frame.depth, CV_16UC1, camera);
    const auto depth_at = [&](float u, float v) {
      if (!raw_depth) return 0.0F;
      const int x = std::clamp(static_cast<int>(std::lround(u)), 0, camera.width - 1);
      const int y = std::clamp(static_cast<int>(std::lround(v)), 0, camera.height - 1);
      return static_cast<float>(frame.depth.at<std::uint16_t>(y, x) / camera.depth_scale);
    };
    // Trials and hits per box (index boxes.size() = outside every box: the frame's rate).
    const std::size_t nb = boxes.size();
    std::vector<std::size_t> kp_n(nb + 1, 0), kp_k(nb + 1, 0), px_n(nb + 1, 0), px_k(nb + 1, 0);
    const auto count = [&](float u, float v, float z, bool hit, std::vector<std::size_t>& n,
                           std::vector<std::size_t>& k) {
      bool inside = false;
      std::optional<Eigen::Vector3f> p;  // back-projected once (undistortion iterates)
      for (std::size_t i = 0; i < nb; ++i) {
        if (!boxes[i] || !in_box(*boxes[i], camera, u, v, z, noise, p)) continue;
        inside = true;
        ++n[i];
        k[i] += hit ? 1U : 0U;
      }
      if (!inside) {
        ++n[nb];
        k[nb] += hit ? 1U : 0U;
      }
    };
    for (const TestedKeypoint& t : geo->last_tested()) {
      count(t.u, t.v, t.z, static_cast<double>(t.chi2) > params_.keypoint_chi2, kp_n, kp_k);
    }
    if (params_.pixel_evidence) {
      // Flagged pixels are a subset of the tested ones (the same grid positions, in order).
      std::vector<std::int64_t> flagged;
      flagged.reserve(geo->last_moving_pixels().size());
      const auto key = [&](const Eigen::Vector2f& q) {
        return static_cast<std::int64_t>(std::lround(q.y())) * camera.width +
               static_cast<std::int64_t>(std::lround(q.x()));
      };
      for (const Eigen::Vector2f& q : geo->last_moving_pixels()) flagged.push_back(key(q));
      std::sort(flagged.begin(), flagged.end());
      for (const Eigen::Vector2f& q : geo->last_warp_tested()) {
        const bool hit = std::binary_search(flagged.begin(), flagged.end(), key(q));
        count(q.x(), q.y(), depth_at(q.x(), q.y()), hit, px_n, px_k);
      }
    }
    // The frame's false-alarm rate outside the boxes (pose error, sensor noise), never below the
    // nominal level of the per-point test; (k + 1) / (n + 2) so that few trials stay cautious.
    const auto rate = [](std::size_t k, std::size_t n, double nominal) {
      return std::max(nominal, (static_cast<double>(k) + 1.0) / (static_cast<double>(n) + 2.0));
    };
    // χ²₃ upper tail at keypoint_chi2 (closed form for 3 dof).
    const double c = params_.keypoint_chi2;
    const double kp_nominal =
        std::erfc(std::sqrt(c / 2.0)) + std::sqrt(2.0 * c / std::numbers::pi) * std::exp(-c / 2.0);
    // The warp's per-pixel test: χ²₁ at warp_chi2.
    const double px_nominal = std::erfc(std::sqrt(geo->params().warp_chi2 / 2.0));
    const double kp_p0 = rate(kp_k[nb], kp_n[nb], kp_nominal);
    const double px_p0 = rate(px_k[nb], px_n[nb], px_nominal);
    // Evidence of this frame per box. 2-D boxes have no world position to track, and evidence in
    // one frame alone is not enough (below): they keep the overlap gate.
    std::vector<std::uint8_t> evidence(nb, 0);
    for (std::size_t i = sem.boxes_2d.size(); i < nb; ++i) {
      if (!boxes[i]) continue;
      const bool kp_ok = binomial_sf(kp_k[i], kp_n[i], kp_p0) < params_.alpha;
      const bool px_ok =
          params_.pixel_evidence && binomial_sf(px_k[i], px_n[i], px_p0) < params_.alpha;
      evidence[i] = kp_ok || px_ok ? 1 : 0;
    }
    const std::size_t n2 = sem.boxes_2d.size();
    // Tracks of 3-D boxes (world frame): evidence in two consecutive frames confirms a track (the
    // geometric source's rule for its candidates), a motion object overlapping the box at once;
    // a confirmed track keeps every box associated with it until hold_frames frames pass without
    // evidence, as the geometric source holds its objects.
    const Eigen::Isometry3d& T_world_cam = geo->last_stats().T_world_cam;
    std::erase_if(tracks_, [&](const Track& t) {
      return now - t.last_evidence > static_cast<std::size_t>(params_.hold_frames);
    });
    std::vector<std::uint8_t> used(tracks_.size(), 0);
    for (std::size_t j = 0; j < sem.boxes_3d.size(); ++j) {
      const std::size_t i = n2 + j;
      if (!boxes[i]) continue;
      const Eigen::Matrix<float, 8, 3>& c3 = sem.boxes_3d[j];
      const Eigen::Vector3d centre = T_world_cam * c3.cast<double>().colwise().mean().transpose();
      const float margin = sem.boxes_3d_margin.empty() ? std::numeric_limits<float>::infinity()
                                                       : sem.boxes_3d_margin[j];
      // Two sightings of one object: their centres differ by up to 3σ of a difference of two
      // uncertain centres, plus what it can move in between. Without a finite uncertainty, half
      // the box's diagonal.
      const double half_diag =
          0.5 * static_cast<double>((c3.colwise().maxCoeff() - c3.colwise().minCoeff()).norm());
      const double reach =
          std::isfinite(margin) ? 3.0 * std::sqrt(2.0) * static_cast<double>(margin) : half_diag;
      std::size_t best = tracks_.size();
      double best_d = std::numeric_limits<double>::infinity();
      for (std::size_t t = 0; t < tracks_.size(); ++t) {
        if (used[t] != 0) continue;
        const double dt = std::max(0.0, frame.timestamp - tracks_[t].timestamp);
        const double d = (centre - tracks_[t].centre_world).norm();
        if (d <= reach + params_.max_speed * dt && d < best_d) {
          best = t;
          best_d = d;
        }
      }
      const bool old = keep[i] != 0;
      const bool ev = old || evidence[i] != 0;
      if (best == tracks_.size()) {
        if (!ev) continue;
        tracks_.push_back(Track{centre, frame.timestamp, now, old});
        used.push_back(1);
        continue;
      }
      Track& t = tracks_[best];
      used[best] = 1;
      if (ev) {
        t.confirmed = t.confirmed || old || t.last_evidence + 1 == now;
        t.last_evidence = now;
      }
      t.centre_world = centre;
      t.timestamp = frame.timestamp;
      if (!old && t.confirmed) {
        keep[i] = 1;
        ++(evidence[i] != 0 ? last_by_evidence_ : last_by_track_);
      }
    }
  }

  // Scores: one per 2-D box when either source gives them (1 for boxes without).
  const bool with_scores = !sem.scores.empty() || !out.scores.empty();
  if (with_scores && out.scores.empty()) out.scores.assign(out.boxes_2d.size(), 1.0F);
  for (std::size_t i = 0; i < sem.boxes_2d.size(); ++i) {
    if (keep[i] == 0) continue;
    out.boxes_2d.push_back(sem.boxes_2d[i]);
    if (with_scores) out.scores.push_back(sem.scores.empty() ? 1.0F : sem.scores[i]);
    ++last_kept_;
  }
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const bool with_margins = !sem.boxes_3d_margin.empty() || !out.boxes_3d_margin.empty();
  if (with_margins) out.boxes_3d_margin.resize(out.boxes_3d.size(), kInf);
  std::vector<std::uint8_t> flags = segmented_flags(out);
  const std::vector<std::uint8_t> sem_flags = segmented_flags(sem);
  bool sem_segmented = false;
  for (std::size_t j = 0; j < sem.boxes_3d.size(); ++j) {
    if (keep[sem.boxes_2d.size() + j] == 0) continue;
    out.boxes_3d.push_back(sem.boxes_3d[j]);
    flags.push_back(sem_flags[j]);
    sem_segmented = sem_segmented || sem_flags[j] != 0U;
    if (with_margins) {
      out.boxes_3d_margin.push_back(sem.boxes_3d_margin.empty() ? kInf : sem.boxes_3d_margin[j]);
    }
    ++last_kept_;
  }
  merge_segmentation(out, std::move(flags), sem, sem_segmented);
  // Under the gate the segmentation decides inside the confirmed boxes only: outside them the
  // part head's foreground has no motion evidence (a seated person who does not move).
  out.segment_outside_boxes = false;
  // The semantic source's floor (the motion source usually has none to give).
  out.support_plane = sem.support_plane ? sem.support_plane : out.support_plane;
  return out;
}

// ---- factory -----------------------------------------------------------------------------------

std::vector<std::filesystem::path> default_weights_candidates() {
  std::vector<std::filesystem::path> out;
#ifdef DS3D_SOURCE_DIR
  out.push_back(std::filesystem::path(DS3D_SOURCE_DIR) / "models" / kDefaultHtxWeights);
#endif
#ifdef DS3D_INSTALL_DATADIR
  out.push_back(std::filesystem::path(DS3D_INSTALL_DATADIR) / "models" / kDefaultHtxWeights);
#endif
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec && !exe.empty()) {
    out.push_back(exe.parent_path().parent_path() / "share" / "ds3d" / "models" /
                  kDefaultHtxWeights);
  }
  return out;
}

std::filesystem::path find_default_weights() {
  const auto candidates = default_weights_candidates();
  std::ostringstream tried;
  for (const auto& p : candidates) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(p, ec)) return p;
    tried << (tried.tellp() > 0 ? ", " : "") << p.string();
  }
  throw IoError(
      detail::concat("ds3d::slam::find_default_weights: no HTx weights file found (tried ",
                     tried.str(), "); pass one with --weights PATH"));
}

std::shared_ptr<DynamicObjectSource> make_dynamic_source(const std::string& spec,
                                                         const DynamicSourceOptions& options) {
  constexpr const char* kKnown =
      "none, geometric, htx, file:PATH, A+B (e.g. htx+geometric), A&B (e.g. htx&geometric) or "
      "A&&geometric (e.g. htx&&geometric)";
  if (spec == "none") return std::make_shared<NoDynamicObjects>();
  if (spec == "geometric") return std::make_shared<GeometricMotionSource>(options.geometric);
  if (spec.rfind("file:", 0) == 0) {
    const std::string path = spec.substr(5);
    DS3D_CHECK(!path.empty(), "ds3d::slam::make_dynamic_source: 'file:' needs a path (got '", spec,
               "')");
    return std::make_shared<FileSource>(path, options.file);
  }
  if (spec == "htx") {
    const std::filesystem::path weights =
        options.weights.empty() ? find_default_weights() : options.weights;
    std::error_code ec;
    DS3D_CHECK_AS(IoError, std::filesystem::is_regular_file(weights, ec),
                  "ds3d::slam::make_dynamic_source: HTx weights file '", weights.string(),
                  "' does not exist or is not a file");
    auto detector = std::make_shared<const SparseDetector>(SparseDetector::load(weights));
    return std::make_shared<HtxSource>(std::move(detector), options.htx);
  }
  if (const auto amp2 = spec.find("&&"); amp2 != std::string::npos) {
    const std::string a = spec.substr(0, amp2);
    const std::string b = spec.substr(amp2 + 2);
    const bool a_ok = a == "geometric" || a == "htx" || (a.rfind("file:", 0) == 0 && a.size() > 5);
    DS3D_CHECK(a_ok && b == "geometric", "ds3d::slam::make_dynamic_source: '", spec,
               "' must gate a source by the geometric source's evidence (expected ", kKnown, ")");
    MotionGateParams gate = options.gate;
    gate.evidence = true;
    // The evidence gate holds confirmed boxes on its own tracks; carried semantic boxes would
    // only be tested again without a new detection (fr1_xyz ATE 0.0115 m without them, 0.0123 m
    // with them).
    DynamicSourceOptions semantic = options;
    semantic.htx.hold_frames = 0;
    return std::make_shared<MotionGatedSource>(make_dynamic_source(a, semantic),
                                               make_dynamic_source(b, options), gate);
  }
  if (const auto amp = spec.find('&'); amp != std::string::npos) {
    const std::string a = spec.substr(0, amp);
    const std::string b = spec.substr(amp + 1);
    const auto simple = [](const std::string& x) {
      return x == "geometric" || x == "htx" || (x.rfind("file:", 0) == 0 && x.size() > 5);
    };
    DS3D_CHECK(simple(a) && simple(b), "ds3d::slam::make_dynamic_source: '", spec,
               "' must gate one source by another, neither none (expected ", kKnown, ")");
    return std::make_shared<MotionGatedSource>(make_dynamic_source(a, options),
                                               make_dynamic_source(b, options), options.gate);
  }
  if (const auto plus = spec.find('+'); plus != std::string::npos) {
    const std::string a = spec.substr(0, plus);
    const std::string b = spec.substr(plus + 1);
    // Both names are checked before either source is built (an htx source loads its weights).
    const auto simple = [](const std::string& x) {
      return x == "geometric" || x == "htx" || (x.rfind("file:", 0) == 0 && x.size() > 5);
    };
    DS3D_CHECK(simple(a) && (simple(b) || b.find('+') != std::string::npos),
               "ds3d::slam::make_dynamic_source: '", spec,
               "' must join two sources other than "
               "none (expected ",
               kKnown, ")");
    return std::make_shared<CompositeSource>(make_dynamic_source(a, options),
                                             make_dynamic_source(b, options));
  }
  throw InvalidArgument(detail::concat("ds3d::slam::make_dynamic_source: unknown source '", spec,
                                       "' (expected ", kKnown, ")"));
}

}  // namespace ds3d::slam
