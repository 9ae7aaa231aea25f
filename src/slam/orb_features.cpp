// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/orb_features.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <numeric>
#include <tuple>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/errors.hpp"

namespace ds3d::slam {
namespace {

constexpr int kPatchRadius = 15;  // half of ORB's 31-pixel patch
constexpr int kEdge = 19;         // OpenCV ORB's edgeThreshold: no descriptor closer to the border
constexpr int kBorder = kEdge + 1;

// Intensity-centroid orientation over a disc of radius 15 (Rosin 1999), in degrees [0, 360).
float ic_angle(const cv::Mat& img, int x, int y) {
  long m01 = 0;
  long m10 = 0;
  for (int v = -kPatchRadius; v <= kPatchRadius; ++v) {
    const int umax =
        static_cast<int>(std::sqrt(static_cast<double>(kPatchRadius * kPatchRadius - v * v)));
    const std::uint8_t* row = img.ptr<std::uint8_t>(y + v);
    for (int u = -umax; u <= umax; ++u) {
      const long val = row[x + u];
      m10 += u * val;
      m01 += v * val;
    }
  }
  float a = cv::fastAtan2(static_cast<float>(m01), static_cast<float>(m10));
  if (a >= 360.0F) a -= 360.0F;
  return a;
}

// FAST corners of one pyramid level bucketed on a grid; cells with no corner retry with the
// lower threshold (ORB-SLAM2's way of keeping features in low-texture areas). One FAST pass over
// the whole level, then per-cell passes only where needed. Returns per-cell lists sorted by
// response (best first), coordinates in the level's pixels.
std::vector<std::vector<cv::KeyPoint>> detect_cells(const cv::Mat& img, const OrbParams& p) {
  const int w = img.cols - 2 * kBorder;
  const int h = img.rows - 2 * kBorder;
  std::vector<std::vector<cv::KeyPoint>> cells;
  if (w < 8 || h < 8) return cells;
  const int nx = std::max(1, w / p.cell_size);
  const int ny = std::max(1, h / p.cell_size);
  cells.resize(static_cast<std::size_t>(nx * ny));
  // Cell of a coordinate: the inverse of x0 = kBorder + cx * w / nx.
  auto cell_of = [&](float x, float y, int* cx, int* cy) {
    const int ix = static_cast<int>(x) - kBorder;
    const int iy = static_cast<int>(y) - kBorder;
    if (ix < 0 || iy < 0 || ix >= w || iy >= h) return false;
    *cx = std::min(nx - 1, (ix * nx) / w);
    *cy = std::min(ny - 1, (iy * ny) / h);
    while (*cx + 1 < nx && ix >= (*cx + 1) * w / nx) ++*cx;
    while (*cx > 0 && ix < *cx * w / nx) --*cx;
    while (*cy + 1 < ny && iy >= (*cy + 1) * h / ny) ++*cy;
    while (*cy > 0 && iy < *cy * h / ny) --*cy;
    return true;
  };
  std::vector<cv::KeyPoint> found;
  // FAST needs a 3-pixel ring: detect inside the border grown by 3 px, keep corners inside cells.
  const cv::Rect inner(kBorder - 3, kBorder - 3, w + 6, h + 6);
  cv::FAST(img(inner), found, p.fast_threshold, true);
  for (auto& k : found) {
    k.pt.x += static_cast<float>(inner.x);
    k.pt.y += static_cast<float>(inner.y);
    int cx = 0;
    int cy = 0;
    if (cell_of(k.pt.x, k.pt.y, &cx, &cy))
      cells[static_cast<std::size_t>(cy * nx + cx)].push_back(k);
  }
  for (int cy = 0; cy < ny; ++cy) {
    for (int cx = 0; cx < nx; ++cx) {
      auto& cell = cells[static_cast<std::size_t>(cy * nx + cx)];
      if (cell.empty() && p.min_fast_threshold < p.fast_threshold) {
        const int x0 = kBorder + cx * w / nx;
        const int x1 = kBorder + (cx + 1) * w / nx;
        const int y0 = kBorder + cy * h / ny;
        const int y1 = kBorder + (cy + 1) * h / ny;
        const cv::Rect roi(x0 - 3, y0 - 3, x1 - x0 + 6, y1 - y0 + 6);
        found.clear();
        cv::FAST(img(roi), found, p.min_fast_threshold, true);
        for (auto& k : found) {
          k.pt.x += static_cast<float>(roi.x);
          k.pt.y += static_cast<float>(roi.y);
          if (k.pt.x >= static_cast<float>(x0) && k.pt.x < static_cast<float>(x1) &&
              k.pt.y >= static_cast<float>(y0) && k.pt.y < static_cast<float>(y1)) {
            cell.push_back(k);
          }
        }
      }
      std::stable_sort(cell.begin(), cell.end(), [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
        return a.response > b.response;
      });
    }
  }
  return cells;
}

// Round-robin over cells (best corner of every cell, then second best, ...) until `quota`:
// spreads features evenly instead of clustering them on the strongest texture. With `spare`,
// the round-robin goes on for `spare_quota` more corners (the next best in the same order).
std::vector<cv::KeyPoint> select_spread(const std::vector<std::vector<cv::KeyPoint>>& cells,
                                        int quota, std::vector<cv::KeyPoint>* spare = nullptr,
                                        int spare_quota = 0) {
  std::vector<cv::KeyPoint> out;
  std::vector<cv::KeyPoint> round;
  const auto by_response = [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
    return a.response > b.response;
  };
  std::size_t rank = 0;
  for (; static_cast<int>(out.size()) < quota; ++rank) {
    round.clear();
    for (const auto& c : cells) {
      if (rank < c.size()) round.push_back(c[rank]);
    }
    if (round.empty()) return out;
    const auto need = static_cast<std::size_t>(quota) - out.size();
    if (round.size() > need) {
      std::stable_sort(round.begin(), round.end(), by_response);
      out.insert(out.end(), round.begin(), round.begin() + static_cast<std::ptrdiff_t>(need));
      if (spare != nullptr)
        spare->assign(round.begin() + static_cast<std::ptrdiff_t>(need), round.end());
      ++rank;
      break;
    }
    out.insert(out.end(), round.begin(), round.end());
  }
  if (spare == nullptr) return out;
  for (; static_cast<int>(spare->size()) < spare_quota; ++rank) {
    round.clear();
    for (const auto& c : cells) {
      if (rank < c.size()) round.push_back(c[rank]);
    }
    if (round.empty()) break;
    spare->insert(spare->end(), round.begin(), round.end());
  }
  if (static_cast<int>(spare->size()) > spare_quota)
    spare->resize(static_cast<std::size_t>(spare_quota));
  return out;
}

}  // namespace

void OrbParams::validate() const {
  constexpr const char* f = "ds3d::slam::OrbParams";
  DS3D_CHECK(num_features > 0, f, ": num_features must be > 0 (got ", num_features, ")");
  DS3D_CHECK(num_levels >= 1 && num_levels <= 16, f, ": num_levels must be in [1, 16] (got ",
             num_levels, ")");
  DS3D_CHECK(std::isfinite(scale_factor) && scale_factor > 1.0 && scale_factor <= 2.0, f,
             ": scale_factor must be in (1, 2] (got ", scale_factor, ")");
  DS3D_CHECK(fast_threshold >= 1 && fast_threshold <= 255, f,
             ": fast_threshold must be in [1, 255] (got ", fast_threshold, ")");
  DS3D_CHECK(min_fast_threshold >= 1 && min_fast_threshold <= fast_threshold, f,
             ": min_fast_threshold must be in [1, fast_threshold] (got ", min_fast_threshold, ")");
  DS3D_CHECK(cell_size >= 8, f, ": cell_size must be >= 8 (got ", cell_size, ")");
  DS3D_CHECK(std::isfinite(max_depth) && max_depth > 0, f, ": max_depth must be > 0 (got ",
             max_depth, ")");
  DS3D_CHECK(std::isfinite(min_depth) && min_depth >= 0 && min_depth < max_depth, f,
             ": min_depth must be in [0, max_depth) (got ", min_depth, ")");
  DS3D_CHECK(std::isfinite(max_range) && max_range >= max_depth, f,
             ": max_range must be >= max_depth (got ", max_range, ")");
}

OrbExtractor::OrbExtractor(const OrbParams& params) : params_(params) {
  params_.validate();
  const auto levels = static_cast<std::size_t>(params_.num_levels);
  scales_.resize(levels);
  for (std::size_t l = 0; l < levels; ++l)
    scales_[l] = std::pow(params_.scale_factor, static_cast<double>(l));
  // Geometric share per level, proportional to the level's area (ORB-SLAM2's ORBextractor).
  const double f = 1.0 / params_.scale_factor;
  const double first = params_.num_features * (1.0 - f) / (1.0 - std::pow(f, params_.num_levels));
  features_per_level_.resize(levels);
  int total = 0;
  for (std::size_t l = 0; l + 1 < levels; ++l) {
    features_per_level_[l] =
        static_cast<int>(std::lround(first * std::pow(f, static_cast<double>(l))));
    total += features_per_level_[l];
  }
  features_per_level_[levels - 1] = std::max(0, params_.num_features - total);
}

OrbFeatures OrbExtractor::extract(const cv::Mat& image, const cv::Mat& depth,
                                  const PinholeCamera& camera) const {
  return extract_impl(image, depth, camera, nullptr, 0, nullptr);
}

OrbFeatures OrbExtractor::extract(const cv::Mat& image, const cv::Mat& depth,
                                  const PinholeCamera& camera, OrbFeatures& spare,
                                  int spare_count) const {
  return extract_impl(image, depth, camera, &spare, spare_count, nullptr);
}

OrbFeatures OrbExtractor::extract(const cv::Mat& image, const cv::Mat& depth,
                                  const PinholeCamera& camera, OrbFeatures& spare, int spare_count,
                                  OrbCorners& corners) const {
  return extract_impl(image, depth, camera, &spare, spare_count, &corners);
}

void OrbExtractor::check_inputs(const cv::Mat* image, const cv::Mat& depth,
                                const PinholeCamera& camera, const char* fn) {
  camera.validate(fn);
  if (image != nullptr) {
    DS3D_CHECK(image->type() == CV_8UC1 || image->type() == CV_8UC3, fn,
               ": image must be CV_8UC1 or CV_8UC3 (got type ", image->type(), ")");
    DS3D_CHECK(image->cols == camera.width && image->rows == camera.height, fn, ": image is ",
               image->cols, "x", image->rows, " but the camera is ", camera.width, "x",
               camera.height);
  }
  DS3D_CHECK(depth.empty() || (depth.type() == CV_16UC1 && depth.cols == camera.width &&
                               depth.rows == camera.height),
             fn, ": depth must be empty or CV_16UC1 of the image size (got type ", depth.type(),
             ", ", depth.cols, "x", depth.rows, ")");
}

OrbFeatures OrbExtractor::extract_impl(const cv::Mat& image, const cv::Mat& depth,
                                       const PinholeCamera& camera, OrbFeatures* spare,
                                       int spare_count, OrbCorners* corners) const {
  check_inputs(&image, depth, camera, "ds3d::slam::OrbExtractor::extract");
  DS3D_CHECK(spare_count >= 0, "ds3d::slam::OrbExtractor::extract: spare_count must be >= 0 (got ",
             spare_count, ")");
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else {
    gray = image;
  }
  std::vector<cv::KeyPoint> keypoints;
  std::vector<cv::KeyPoint> spare_kp;
  detect_levels(gray, keypoints, spare != nullptr ? &spare_kp : nullptr, spare_count, corners);
  if (corners != nullptr) {
    corners->width = gray.cols;
    corners->height = gray.rows;
    corners->params = params_;
    corners->picked = keypoints;
  }
  OrbFeatures out = describe_gray(gray, std::move(keypoints), depth, camera);
  if (corners != nullptr) {
    corners->described.keypoints = out.keypoints;
    corners->described.descriptors = out.descriptors;
  }
  if (spare != nullptr) {
    *spare = OrbFeatures{};
    spare->keypoints = std::move(spare_kp);
  }
  return out;
}

bool OrbCorners::shares_pyramid(const OrbParams& p, int w, int h) const noexcept {
  return w == width && h == height && p.num_levels == params.num_levels &&
         p.scale_factor == params.scale_factor && p.fast_threshold == params.fast_threshold &&
         p.min_fast_threshold == params.min_fast_threshold && p.cell_size == params.cell_size;
}

std::optional<OrbFeatures> OrbExtractor::extract_from(const OrbCorners& corners,
                                                      const cv::Mat& depth,
                                                      const PinholeCamera& camera) const {
  check_inputs(nullptr, depth, camera, "ds3d::slam::OrbExtractor::extract_from");
  if (!corners.shares_pyramid(params_, camera.width, camera.height) ||
      corners.picked.size() != corners.described.keypoints.size() ||
      corners.cells.size() > scales_.size()) {
    return std::nullopt;
  }
  // The described keypoints by (level, y, x) of what was handed to the descriptor.
  const auto key = [](const cv::KeyPoint& k) { return std::make_tuple(k.octave, k.pt.y, k.pt.x); };
  std::vector<std::uint32_t> order(corners.picked.size());
  std::iota(order.begin(), order.end(), 0U);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return key(corners.picked[a]) < key(corners.picked[b]);
  });
  std::vector<std::uint32_t> rows;
  rows.reserve(static_cast<std::size_t>(params_.num_features));
  for (std::size_t l = 0; l < corners.cells.size(); ++l) {
    const double s = scales_[l];
    for (const cv::KeyPoint& k : select_spread(corners.cells[l], features_per_level_[l])) {
      const auto want = std::make_tuple(static_cast<int>(l), static_cast<float>(k.pt.y * s),
                                        static_cast<float>(k.pt.x * s));
      const auto it = std::lower_bound(
          order.begin(), order.end(), want,
          [&](std::uint32_t i, const auto& w) { return key(corners.picked[i]) < w; });
      if (it == order.end() || key(corners.picked[*it]) != want) return std::nullopt;
      rows.push_back(*it);
    }
  }
  OrbFeatures out;
  out.keypoints.reserve(rows.size());
  if (!rows.empty()) {
    out.descriptors.create(static_cast<int>(rows.size()), corners.described.descriptors.cols,
                           corners.described.descriptors.type());
  }
  for (std::size_t r = 0; r < rows.size(); ++r) {
    out.keypoints.push_back(corners.described.keypoints[rows[r]]);
    corners.described.descriptors.row(static_cast<int>(rows[r]))
        .copyTo(out.descriptors.row(static_cast<int>(r)));
  }
  attach_geometry(out, depth, camera);
  return out;
}

OrbFeatures OrbExtractor::describe(const cv::Mat& image, std::vector<cv::KeyPoint> keypoints,
                                   const cv::Mat& depth, const PinholeCamera& camera) const {
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else {
    gray = image;
  }
  return describe_gray(gray, std::move(keypoints), depth, camera);
}

OrbFeatures OrbExtractor::describe_gray(const cv::Mat& gray, std::vector<cv::KeyPoint> keypoints,
                                        const cv::Mat& depth, const PinholeCamera& camera) const {
  OrbFeatures out;
  if (!keypoints.empty()) {
    // Descriptors only: OpenCV rebuilds the same 1.2-scale pyramid and reads each keypoint at
    // its octave with the angle computed above.
    auto orb = cv::ORB::create(params_.num_features, static_cast<float>(params_.scale_factor),
                               params_.num_levels, kEdge, 0, 2, cv::ORB::FAST_SCORE, 31,
                               params_.fast_threshold);
    orb->compute(gray, keypoints, out.descriptors);
  }
  out.keypoints = std::move(keypoints);
  attach_geometry(out, depth, camera);
  return out;
}

void OrbExtractor::detect_levels(const cv::Mat& gray, std::vector<cv::KeyPoint>& keypoints,
                                 std::vector<cv::KeyPoint>* spare, int spare_count,
                                 OrbCorners* corners) const {
  if (corners != nullptr) corners->cells.clear();
  keypoints.reserve(static_cast<std::size_t>(params_.num_features) + 16);
  cv::Mat level_img = gray;
  std::vector<cv::KeyPoint> level_spare;
  for (int l = 0; l < params_.num_levels; ++l) {
    const double s = scales_[static_cast<std::size_t>(l)];
    if (l > 0) {
      const cv::Size sz(static_cast<int>(std::lround(gray.cols / s)),
                        static_cast<int>(std::lround(gray.rows / s)));
      if (sz.width <= 2 * kBorder + 8 || sz.height <= 2 * kBorder + 8) break;
      cv::Mat next;
      cv::resize(level_img, next, sz, 0, 0, cv::INTER_LINEAR);
      level_img = next;
    }
    auto cells = detect_cells(level_img, params_);
    const int quota = features_per_level_[static_cast<std::size_t>(l)];
    // The spare budget of a level follows the same geometric share as its primary one.
    const int spare_quota = static_cast<int>(
        std::lround(static_cast<double>(spare_count) * quota / params_.num_features));
    level_spare.clear();
    auto picked =
        select_spread(cells, quota, spare != nullptr ? &level_spare : nullptr, spare_quota);
    const auto finish = [&](cv::KeyPoint& k) {
      k.angle = ic_angle(level_img, static_cast<int>(k.pt.x), static_cast<int>(k.pt.y));
      k.pt.x = static_cast<float>(k.pt.x * s);
      k.pt.y = static_cast<float>(k.pt.y * s);
      k.size = static_cast<float>(31.0 * s);
      k.octave = l;
    };
    for (auto& k : picked) {
      finish(k);
      keypoints.push_back(k);
    }
    if (corners != nullptr) corners->cells.push_back(std::move(cells));
    if (spare == nullptr) continue;
    for (auto& k : level_spare) {
      finish(k);
      spare->push_back(k);
    }
  }
}

// Undistorted pixels and the depth at each keypoint.
void OrbExtractor::attach_geometry(OrbFeatures& out, const cv::Mat& depth,
                                   const PinholeCamera& camera) const {
  out.close_depth = static_cast<float>(params_.max_depth);
  const std::size_t n = out.keypoints.size();
  out.undistorted.resize(n);
  out.depth.assign(n, 0.0F);
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Point2f& pt = out.keypoints[i].pt;
    const Eigen::Vector2d xn =
        camera.undistort({(pt.x - camera.cx) / camera.fx, (pt.y - camera.cy) / camera.fy});
    out.undistorted[i] = Eigen::Vector2f(static_cast<float>(camera.fx * xn.x() + camera.cx),
                                         static_cast<float>(camera.fy * xn.y() + camera.cy));
    if (!depth.empty()) {
      const int x = std::clamp(static_cast<int>(std::lround(pt.x)), 0, depth.cols - 1);
      const int y = std::clamp(static_cast<int>(std::lround(pt.y)), 0, depth.rows - 1);
      const double z = depth.at<std::uint16_t>(y, x) / camera.depth_scale;
      if (z >= params_.min_depth && z <= params_.max_range) out.depth[i] = static_cast<float>(z);
    }
  }
}

int descriptor_distance(const std::uint8_t* a, const std::uint8_t* b) noexcept {
  int d = 0;
  for (int k = 0; k < 4; ++k) {
    std::uint64_t x = 0;
    std::uint64_t y = 0;
    std::memcpy(&x, a + 8 * k, 8);
    std::memcpy(&y, b + 8 * k, 8);
    d += std::popcount(x ^ y);
  }
  return d;
}

}  // namespace ds3d::slam
