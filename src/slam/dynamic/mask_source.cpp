// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// MaskSource.
#include "ds3d/slam/dynamic/mask_source.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <opencv2/imgcodecs.hpp>
#include <system_error>

#include "ds3d/errors.hpp"

namespace ds3d::slam {

namespace {

// The timestamp a file's stem spells ("1700000000.033333"), or NaN.
double stem_timestamp(const std::filesystem::path& p) {
  const std::string s = p.stem().string();
  if (s.empty()) return std::nan("");
  char* end = nullptr;
  const double t = std::strtod(s.c_str(), &end);
  return end != nullptr && *end == '\0' && std::isfinite(t) ? t : std::nan("");
}

}  // namespace

MaskSource::MaskSource(const std::filesystem::path& dir, double max_dt) : max_dt_(max_dt) {
  DS3D_CHECK(std::isfinite(max_dt) && max_dt >= 0.0,
             "ds3d::slam::MaskSource: max_dt must be finite and >= 0 (got ", max_dt, ")");
  std::error_code ec;
  DS3D_CHECK_AS(IoError, std::filesystem::is_directory(dir, ec), "ds3d::slam::MaskSource: '",
                dir.string(), "' is not a folder");
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    if (!e.is_regular_file(ec)) continue;
    const double t = stem_timestamp(e.path());
    if (!std::isnan(t)) masks_.emplace_back(t, e.path());
  }
  DS3D_CHECK_AS(IoError, !masks_.empty(), "ds3d::slam::MaskSource: folder '", dir.string(),
                "' holds no image named by a timestamp (e.g. 1700000000.033333.png)");
  std::sort(masks_.begin(), masks_.end());
}

DynamicObjects MaskSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  DynamicObjects out;
  const auto it = std::lower_bound(masks_.begin(), masks_.end(), frame.timestamp,
                                   [](const auto& m, double t) { return m.first < t; });
  const auto* best = it == masks_.end() ? nullptr : &*it;
  if (it != masks_.begin()) {
    const auto* prev = &*std::prev(it);
    if (best == nullptr ||
        std::abs(prev->first - frame.timestamp) <= std::abs(best->first - frame.timestamp)) {
      best = prev;
    }
  }
  if (best == nullptr || std::abs(best->first - frame.timestamp) > max_dt_) {
    ++unmatched_;
    return out;
  }
  cv::Mat m = cv::imread(best->second.string(), cv::IMREAD_GRAYSCALE);
  DS3D_CHECK_AS(IoError, !m.empty(), "ds3d::slam::MaskSource: cannot read mask image '",
                best->second.string(), "'");
  DS3D_CHECK_AS(IoError, m.cols == camera.width && m.rows == camera.height,
                "ds3d::slam::MaskSource: mask image '", best->second.string(), "' is ", m.cols, "x",
                m.rows, ", the camera is ", camera.width, "x", camera.height);
  ++matched_;
  out.pixel_mask = m;
  return out;
}

}  // namespace ds3d::slam
