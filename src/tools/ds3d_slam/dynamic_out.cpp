// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-slam's record of the dynamic stages per frame: boxes for --viz, masks for --dynamic-out.
#include "dynamic_out.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string_view>
#include <system_error>
#include <utility>

#include <opencv2/imgcodecs.hpp>

// GCC 12 -O3 reports a false -Wrestrict inside std::string::insert as inlined into
// detail::write_file_atomically; silence it for these headers only (as ds3d_slam.cpp does).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wrestrict"
#include "ds3d/detail/json.hpp"
#include "ds3d/detail/tum_text.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"
#pragma GCC diagnostic pop

namespace ds3d_slam_tool {

cv::Mat dynamic_mask(const std::vector<ds3d::ImageBox>& boxes, const cv::Mat& pixel_mask, int width,
                     int height) {
  cv::Mat out(height, width, CV_8UC1, cv::Scalar(0));
  // The pixels a point of the box rounds to (std::lround, as the masker rounds keypoints):
  // columns lround(x_min) .. lround(x_max), rows likewise, clipped to the image.
  const auto px = [](float v, int hi) {
    return static_cast<int>(std::lround(std::clamp(v, -1.0F, static_cast<float>(hi) + 1.0F)));
  };
  for (const auto& b : boxes) {
    const int x0 = std::max(0, px(b.x_min, width));
    const int y0 = std::max(0, px(b.y_min, height));
    const int x1 = std::min(width - 1, px(b.x_max, width));
    const int y1 = std::min(height - 1, px(b.y_max, height));
    if (x1 < x0 || y1 < y0) continue;
    out(cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1)).setTo(255);
  }
  if (pixel_mask.type() == CV_8UC1 && pixel_mask.cols == width && pixel_mask.rows == height) {
    out.setTo(255, pixel_mask != 0);
  }
  return out;
}

std::vector<std::uint8_t> RecordingMasker::mask(const ds3d::slam::FrameInput& frame,
                                                const ds3d::PinholeCamera& camera,
                                                const ds3d::slam::OrbFeatures& features,
                                                const ds3d::slam::DynamicObjects& objects) {
  auto m = inner_.mask(frame, camera, features, objects);
  if (record_boxes_ || record_mask_) {
    DynamicRecord rec;
    for (const auto& b : inner_.last_result().boxes) rec.boxes.push_back(b.box);
    if (record_mask_) {
      rec.mask = dynamic_mask(rec.boxes, objects.pixel_mask, camera.width, camera.height);
    }
    if (!record_boxes_) rec.boxes.clear();
    const std::lock_guard<std::mutex> lock(mutex_);
    records_[frame.index] = std::move(rec);
  }
  return m;
}

DynamicRecord RecordingMasker::take(std::size_t index) {
  const std::lock_guard<std::mutex> lock(mutex_);
  const auto it = records_.find(index);
  if (it == records_.end()) return {};
  auto out = std::move(it->second);
  records_.erase(it);
  return out;
}

const char* status_name(ds3d::slam::KeypointStatus s) noexcept {
  switch (s) {
    case ds3d::slam::KeypointStatus::kUnmatched:
      return "unmatched";
    case ds3d::slam::KeypointStatus::kTracked:
      return "tracked";
    case ds3d::slam::KeypointStatus::kDynamic:
      return "dynamic";
    case ds3d::slam::KeypointStatus::kDepthEdge:
      return "depth_edge";
  }
  return "unknown";
}

namespace {

// Shortest round-trip decimal of a pixel coordinate (null when not finite: JSON has no NaN).
void append_float(std::string& out, float v) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, res.ptr);
}

// The mask's file name: the rgb image's stem when it spells a number (TUM, Bonn and ds3d-synth
// name images by their timestamp), else the timestamp with 6 decimals as in TUM lists.
std::string mask_name(const std::string& rgb_file, double timestamp) {
  const std::string stem = std::filesystem::path(rgb_file).stem().string();
  double v = 0;
  const auto res = std::from_chars(stem.data(), stem.data() + stem.size(), v);
  if (!stem.empty() && res.ec == std::errc() && res.ptr == stem.data() + stem.size()) {
    return stem + ".png";
  }
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f.png", timestamp);
  return buf;
}

}  // namespace

DynamicOutWriter::DynamicOutWriter(std::filesystem::path dir, const ds3d::RgbdDataset& dataset)
    : dir_(std::move(dir)), dataset_(dataset) {
  const auto path = dir_ / "keypoints.jsonl";
  jsonl_.open(path, std::ios::binary | std::ios::trunc);
  DS3D_CHECK_AS(ds3d::IoError, jsonl_.is_open(), "--dynamic-out: cannot create ", path.string());
}

void DynamicOutWriter::write(const ds3d::slam::TrackResult& r, const cv::Mat& mask) {
  const auto& cam = dataset_.camera();
  const cv::Mat img = mask.empty() ? cv::Mat(cam.height, cam.width, CV_8UC1, cv::Scalar(0)) : mask;
  const std::string name = mask_name(dataset_.entries()[r.index].rgb_file, r.timestamp);
  std::vector<std::uint8_t> png;
  const auto path = dir_ / name;
  DS3D_CHECK_AS(ds3d::IoError, cv::imencode(".png", img, png), "--dynamic-out: cannot encode ",
                path.string());
  ds3d::detail::write_file_atomically(
      path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()),
      "--dynamic-out");
  std::string line = "{\"timestamp\": ";
  ds3d::detail::append_double(line, r.timestamp);
  line += ", \"frame\": " + std::to_string(r.index) + ", \"mask\": \"" +
          ds3d::detail::json_escape(name) + "\", \"u\": [";
  for (std::size_t i = 0; i < r.keypoints.size(); ++i) {
    if (i > 0) line += ", ";
    append_float(line, r.keypoints[i].x);
  }
  line += "], \"v\": [";
  for (std::size_t i = 0; i < r.keypoints.size(); ++i) {
    if (i > 0) line += ", ";
    append_float(line, r.keypoints[i].y);
  }
  line += "], \"status\": [";
  for (std::size_t i = 0; i < r.keypoint_status.size(); ++i) {
    line += i > 0 ? ", \"" : "\"";
    line += status_name(r.keypoint_status[i]);
    line += '"';
  }
  line += "]}\n";
  jsonl_.write(line.data(), static_cast<std::streamsize>(line.size()));
  jsonl_.flush();
  DS3D_CHECK_AS(ds3d::IoError, jsonl_.good(), "--dynamic-out: cannot write ",
                (dir_ / "keypoints.jsonl").string());
}

}  // namespace ds3d_slam_tool
