// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file detections.hpp
/// @brief Per-frame object detections from a JSON-lines file, so that any external detector can
/// drive ds3d's dynamic-feature removal (header-only, no OpenCV).
///
/// Format: one JSON object per line (blank lines and lines starting with '#' are skipped):
/// @code
/// {"timestamp": 1305031102.175, "boxes": [
///   {"bbox": [x_min, y_min, x_max, y_max], "score": 0.93, "class": "person"},
///   {"corners": [[x, y, z], ... 8 rows ...], "score": 0.8, "class": "person"}]}
/// @endcode
/// `bbox` is an image box [px, raw image, pixel-centre convention]; `corners` are the 8 corners
/// of a 3-D box in the camera frame (x right, y down, z forward) [m], any order. Each box has
/// exactly one of the two. `score` (default 1) is in [0, 1]; `class` (default "") is free text.
/// Frames need not be sorted; a timestamp may not appear twice.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ds3d/detail/json.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// One detected object: a 2-D image box or a 3-D box (camera-frame corners).
struct Detection {
  bool is_3d = false;  ///< true: `corners` is set; false: `box` is set
  ImageBox box;        ///< 2-D box [px] (score copied in)
  Eigen::Matrix<float, 8, 3> corners = Eigen::Matrix<float, 8, 3>::Zero();  ///< 3-D box [m]
  float score = 1.0F;  ///< confidence in [0, 1]
  std::string cls;     ///< class name ("" when not given)
};

/// The detections of one frame.
struct DetectionFrame {
  double timestamp = 0.0;             ///< [s]
  std::vector<Detection> detections;  ///< may be empty (the detector saw nothing)
};

/// All frames of a detections file, sorted by timestamp.
class DetectionsFile {
 public:
  DetectionsFile() = default;

  /// Reads a JSON-lines detections file.
  /// @throws ds3d::IoError when the file cannot be read, or naming the file, line and field when a
  ///   line is malformed (bad JSON, missing timestamp, a box with neither or both of bbox and
  ///   corners, wrong array sizes, non-finite numbers, score outside [0, 1], x_max < x_min, a
  ///   duplicate timestamp).
  /// @note O(file size + F log F) for F frames.
  [[nodiscard]] static DetectionsFile read(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    DS3D_CHECK_AS(IoError, in.good(), "ds3d::DetectionsFile::read: cannot open '", path.string(),
                  "'");
    std::ostringstream ss;
    ss << in.rdbuf();
    return parse(ss.str(), path.string());
  }

  /// Parses the content of a detections file; `name` only appears in error messages.
  /// @throws ds3d::IoError as read().
  [[nodiscard]] static DetectionsFile parse(const std::string& text,
                                            const std::string& name = "<string>");

  /// The frame whose timestamp is nearest to `timestamp`, if within `max_dt` seconds.
  /// @param timestamp [s]  @param max_dt [s], >= 0
  /// @note O(log F). Ties go to the earlier frame.
  [[nodiscard]] const DetectionFrame* find(double timestamp, double max_dt) const {
    if (frames_.empty() || !std::isfinite(timestamp)) return nullptr;
    const auto it =
        std::lower_bound(frames_.begin(), frames_.end(), timestamp,
                         [](const DetectionFrame& f, double t) { return f.timestamp < t; });
    const DetectionFrame* best = nullptr;
    double best_dt = 0.0;
    const auto consider = [&](const DetectionFrame& f) {
      const double dt = std::abs(f.timestamp - timestamp);
      if (dt <= max_dt && (best == nullptr || dt < best_dt)) {
        best = &f;
        best_dt = dt;
      }
    };
    if (it != frames_.begin()) consider(*std::prev(it));
    if (it != frames_.end()) consider(*it);
    return best;
  }

  /// All frames, sorted by timestamp.
  [[nodiscard]] const std::vector<DetectionFrame>& frames() const noexcept { return frames_; }

 private:
  std::vector<DetectionFrame> frames_;
};

inline DetectionsFile DetectionsFile::parse(const std::string& text, const std::string& name) {
  DetectionsFile out;
  std::istringstream in(text);
  std::size_t line_no = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    const auto where = [&] { return detail::concat(name, ":", line_no); };
    const auto num = [&](const detail::JsonValue& v, const char* what) {
      const double d = v.as_number();
      DS3D_CHECK_AS(IoError, std::isfinite(d), "ds3d::DetectionsFile: ", where(), ": ", what,
                    " must be finite (got ", d, ")");
      return d;
    };
    DetectionFrame frame;
    try {
      const detail::JsonValue doc = detail::parse_json(line);
      DS3D_CHECK_AS(IoError, doc.is_object(), "ds3d::DetectionsFile: ", where(),
                    ": each line must be a JSON object");
      frame.timestamp = num(doc.at("timestamp"), "timestamp");
      if (doc.contains("boxes")) {
        const auto& boxes = doc.at("boxes").as_array();
        for (std::size_t b = 0; b < boxes.size(); ++b) {
          const auto& jb = boxes[b];
          Detection d;
          const bool has2 = jb.contains("bbox");
          const bool has3 = jb.contains("corners");
          DS3D_CHECK_AS(IoError, has2 != has3, "ds3d::DetectionsFile: ", where(), ": boxes[", b,
                        "] needs exactly one of 'bbox' and 'corners'");
          if (jb.contains("score")) d.score = static_cast<float>(num(jb.at("score"), "score"));
          DS3D_CHECK_AS(IoError, d.score >= 0.0F && d.score <= 1.0F,
                        "ds3d::DetectionsFile: ", where(), ": boxes[", b,
                        "].score must be in [0, 1] (got ", d.score, ")");
          if (jb.contains("class")) d.cls = jb.at("class").as_string();
          if (has2) {
            const auto& a = jb.at("bbox");
            DS3D_CHECK_AS(IoError, a.size() == 4 && a.is_array(), "ds3d::DetectionsFile: ", where(),
                          ": boxes[", b, "].bbox must have 4 numbers");
            d.box.x_min = static_cast<float>(num(a.at(0), "bbox"));
            d.box.y_min = static_cast<float>(num(a.at(1), "bbox"));
            d.box.x_max = static_cast<float>(num(a.at(2), "bbox"));
            d.box.y_max = static_cast<float>(num(a.at(3), "bbox"));
            DS3D_CHECK_AS(IoError, d.box.x_max >= d.box.x_min && d.box.y_max >= d.box.y_min,
                          "ds3d::DetectionsFile: ", where(), ": boxes[", b,
                          "].bbox must have x_max >= x_min and y_max >= y_min");
            d.box.score = d.score;
          } else {
            const auto& a = jb.at("corners");
            DS3D_CHECK_AS(IoError, a.size() == 8 && a.is_array(), "ds3d::DetectionsFile: ", where(),
                          ": boxes[", b, "].corners must have 8 rows");
            for (std::size_t r = 0; r < 8; ++r) {
              DS3D_CHECK_AS(IoError, a.at(r).is_array() && a.at(r).size() == 3,
                            "ds3d::DetectionsFile: ", where(), ": boxes[", b, "].corners[", r,
                            "] must have 3 numbers");
              for (std::size_t c = 0; c < 3; ++c) {
                d.corners(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) =
                    static_cast<float>(num(a.at(r).at(c), "corners"));
              }
            }
            d.is_3d = true;
          }
          frame.detections.push_back(std::move(d));
        }
      }
    } catch (const IoError& e) {
      const std::string msg = e.what();
      if (msg.rfind("ds3d::DetectionsFile", 0) == 0) throw;
      throw IoError(detail::concat("ds3d::DetectionsFile: ", where(), ": ", msg));
    }
    out.frames_.push_back(std::move(frame));
  }
  std::stable_sort(
      out.frames_.begin(), out.frames_.end(),
      [](const DetectionFrame& a, const DetectionFrame& b) { return a.timestamp < b.timestamp; });
  for (std::size_t i = 1; i < out.frames_.size(); ++i) {
    DS3D_CHECK_AS(IoError, out.frames_[i].timestamp != out.frames_[i - 1].timestamp,
                  "ds3d::DetectionsFile: ", name, ": duplicate timestamp ",
                  out.frames_[i].timestamp);
  }
  return out;
}

}  // namespace ds3d
