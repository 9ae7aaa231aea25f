// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/dataset.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <system_error>

#include <opencv2/imgcodecs.hpp>

#include "ds3d/detail/tum_text.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"

namespace ds3d {

namespace fs = std::filesystem;

namespace {

/// Intrinsics of the named presets (640 x 480, depth_scale 5000): the TUM RGB-D benchmark's
/// calibrations (fr1, fr2, fr3 = already undistorted) and the Bonn RGB-D Dynamic dataset's.
struct CameraPreset {
  std::string_view name;
  double fx, fy, cx, cy, k1, k2, p1, p2, k3;
};

constexpr std::array<CameraPreset, 4> kCameraPresets{{
    {"tum1", 517.306408, 516.469215, 318.643040, 255.313989, 0.262383, -0.953104, -0.005358,
     0.002628, 1.163314},
    {"tum2", 520.908620, 521.007327, 325.141442, 249.701764, 0.231222, -0.784899, -0.003257,
     -0.000105, 0.917205},
    {"tum3", 535.4, 539.2, 320.1, 247.6, 0.0, 0.0, 0.0, 0.0, 0.0},
    {"bonn", 542.822841, 542.576870, 315.593520, 237.756098, 0.039903, -0.099343, -0.000730,
     -0.000144, 0.0},
}};

// Gaps between consecutive associated frames longer than max(1 s, 10 x the median interval).
void find_gaps(const std::vector<RgbdEntry>& entries, DatasetDiagnostics& d) {
  std::vector<double> dt;
  for (std::size_t i = 1; i < entries.size(); ++i)
    dt.push_back(entries[i].timestamp - entries[i - 1].timestamp);
  if (dt.empty()) return;
  std::vector<double> sorted = dt;
  const std::size_t mid = (sorted.size() - 1) / 2;  // the lower median
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(mid), sorted.end());
  d.gap_threshold = std::max(1.0, 10.0 * sorted[mid]);
  for (std::size_t i = 0; i < dt.size(); ++i) {
    if (!(dt[i] > d.gap_threshold)) continue;
    if (d.large_gaps++ == 0) {
      d.first_gap_start = entries[i].timestamp;
      d.first_gap_seconds = dt[i];
    }
  }
}

// True when the file starts like a JPEG (FF D8) but lacks the end-of-image marker (FF D9) in
// its last 64 bytes (trailing padding allowed): libjpeg decodes such a file with a warning only.
bool is_truncated_jpeg(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  char head[2] = {};
  if (!in.read(head, 2) || head[0] != '\xFF' || head[1] != '\xD8') return false;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  const std::streamoff tail = std::min<std::streamoff>(size, 64);
  std::string buf(static_cast<std::size_t>(tail), '\0');
  in.seekg(size - tail);
  if (!in.read(buf.data(), tail)) return false;  // unreadable: imread reports it
  return buf.find("\xFF\xD9") == std::string::npos;
}

}  // namespace

PinholeCamera camera_preset(std::string_view name) {
  PinholeCamera c;  // 640 x 480, depth_scale 5000, ROS default intrinsics
  if (name == "tum_ros") return c;
  for (const CameraPreset& p : kCameraPresets) {
    if (p.name != name) continue;
    c.fx = p.fx;
    c.fy = p.fy;
    c.cx = p.cx;
    c.cy = p.cy;
    c.k1 = p.k1;
    c.k2 = p.k2;
    c.p1 = p.p1;
    c.p2 = p.p2;
    c.k3 = p.k3;
    return c;
  }
  throw InvalidArgument(detail::concat("ds3d::camera_preset: unknown name '", name,
                                       "' (valid: tum1, tum2, tum3, tum_ros, bonn)"));
}

namespace {

/// Ranges a real RGB-D camera stays in; values outside them (a focal length of 1e-300 px, a
/// principal point at 1e300 px) lose every frame instead of failing, so the reader refuses them.
constexpr double kMinFocal = 1.0;        // [px]
constexpr double kMaxFocal = 1e5;        // [px]
constexpr double kMinDepthScale = 1e-6;  // [depth units per metre]
constexpr double kMaxDepthScale = 1e9;   // [depth units per metre]

void check_plausible(const PinholeCamera& c, std::string_view source) {
  const auto in = [&](const char* key, double v, double lo, double hi, const char* unit) {
    DS3D_CHECK_AS(IoError, v >= lo && v <= hi, "ds3d::read_camera_file: ", source, ": ", key,
                  " must be in [", lo, ", ", hi, "] ", unit, " (got ", v, ")");
  };
  in("fx", c.fx, kMinFocal, kMaxFocal, "px");
  in("fy", c.fy, kMinFocal, kMaxFocal, "px");
  // The principal point may lie off a cropped image, but not more than one image size off.
  in("cx", c.cx, -c.width, 2.0 * c.width, "px (-width to 2 width)");
  in("cy", c.cy, -c.height, 2.0 * c.height, "px (-height to 2 height)");
  in("depth_scale", c.depth_scale, kMinDepthScale, kMaxDepthScale, "units per metre");
}

}  // namespace

PinholeCamera parse_camera_text(std::string_view text, std::string_view source) {
  constexpr const char* kFn = "ds3d::read_camera_file";
  PinholeCamera c;
  std::map<std::string, double, std::less<>> values;
  static const std::array<std::string_view, 12> kKeys = {
      "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "depth_scale", "width", "height"};
  for (const auto& line : detail::split_tum_lines(text)) {
    if (line.tokens.empty()) continue;
    DS3D_CHECK_AS(IoError, line.tokens.size() == 2, kFn, ": ", source, " line ", line.number,
                  ": expected 'key value' (got ", line.tokens.size(), " tokens)");
    const std::string_view key = line.tokens[0];
    DS3D_CHECK_AS(IoError, std::find(kKeys.begin(), kKeys.end(), key) != kKeys.end(), kFn, ": ",
                  source, " line ", line.number, ": unknown key '", key,
                  "' (valid: fx fy cx cy k1 k2 p1 p2 k3 depth_scale width height)");
    DS3D_CHECK_AS(IoError, values.find(key) == values.end(), kFn, ": ", source, " line ",
                  line.number, ": key '", key, "' repeated");
    const auto v = detail::parse_py_float(line.tokens[1]);
    DS3D_CHECK_AS(IoError, v.has_value() && std::isfinite(*v), kFn, ": ", source, " line ",
                  line.number, ": value of '", key, "' is not a finite number ('", line.tokens[1],
                  "')");
    values.emplace(std::string(key), *v);
  }
  for (const char* req : {"fx", "fy", "cx", "cy"}) {
    DS3D_CHECK_AS(IoError, values.count(req) == 1, kFn, ": ", source, ": missing key '", req, "'");
  }
  const auto get = [&](const char* k, double def) {
    const auto it = values.find(k);
    return it == values.end() ? def : it->second;
  };
  c.fx = get("fx", c.fx);
  c.fy = get("fy", c.fy);
  c.cx = get("cx", c.cx);
  c.cy = get("cy", c.cy);
  c.k1 = get("k1", 0);
  c.k2 = get("k2", 0);
  c.p1 = get("p1", 0);
  c.p2 = get("p2", 0);
  c.k3 = get("k3", 0);
  c.depth_scale = get("depth_scale", c.depth_scale);
  for (const char* k : {"width", "height"}) {
    const double v = get(k, 0);
    DS3D_CHECK_AS(IoError, v == std::floor(v) && v >= 0 && v < 1e6, kFn, ": ", source, ": ", k,
                  " must be a positive integer (got ", v, ")");
  }
  c.width = static_cast<int>(get("width", c.width));
  c.height = static_cast<int>(get("height", c.height));
  try {
    c.validate(kFn);
  } catch (const InvalidArgument& e) {
    throw IoError(detail::concat(e.what(), " in ", source));
  }
  check_plausible(c, source);
  return c;
}

PinholeCamera read_camera_file(const fs::path& path) {
  return parse_camera_text(detail::read_text_file(path, "ds3d::read_camera_file"), path.string());
}

std::optional<std::string> camera_preset_for_folder(const fs::path& dir) {
  fs::path p = dir.lexically_normal();
  if (!p.has_filename()) p = p.parent_path();  // "a/b/" -> "a/b"
  const std::string name = p.filename().string();
  const auto starts = [&](std::string_view prefix) { return name.rfind(prefix, 0) == 0; };
  if (starts("rgbd_dataset_freiburg1_")) return "tum1";
  if (starts("rgbd_dataset_freiburg2_")) return "tum2";
  if (starts("rgbd_dataset_freiburg3_")) return "tum3";
  if (starts("rgbd_bonn_")) return "bonn";
  return std::nullopt;
}

namespace {

/// Camera of a folder without camera.txt: the preset its name selects, else the ROS default. Says
/// which on stderr (one line), loudly when nothing identified the camera.
PinholeCamera camera_without_file(const fs::path& dir) {
  const auto preset = camera_preset_for_folder(dir);
  const PinholeCamera c = camera_preset(preset.value_or("tum_ros"));
  if (preset) {
    std::cerr << "ds3d: info: no camera.txt in '" << dir.string() << "'; folder name -> preset '"
              << *preset << "' (fx " << c.fx << " fy " << c.fy << " cx " << c.cx << " cy " << c.cy
              << ")\n";
  } else {
    std::cerr << "ds3d: WARNING: no camera.txt in '" << dir.string()
              << "' and no known dataset folder name: using default intrinsics 'tum_ros' (fx "
              << c.fx << " fy " << c.fy << " cx " << c.cx << " cy " << c.cy
              << ", no distortion, depth_scale " << c.depth_scale
              << "); add camera.txt or pass a camera if they are wrong\n";
  }
  return c;
}

}  // namespace

RgbdDataset RgbdDataset::open(const fs::path& dir, const DatasetOptions& options) {
  constexpr const char* kFn = "ds3d::RgbdDataset::open";
  DS3D_CHECK(std::isfinite(options.max_difference) && options.max_difference >= 0, kFn,
             ": max_difference must be finite and >= 0 (got ", options.max_difference, ")");
  DS3D_CHECK(std::isfinite(options.offset), kFn, ": offset must be finite (got ", options.offset,
             ")");
  std::error_code ec;
  DS3D_CHECK_AS(IoError, fs::is_directory(dir, ec), kFn, ": not a directory: '", dir.string(), "'");
  const auto read_list = [&](const char* name, std::vector<double>& duplicates) {
    const fs::path p = dir / name;
    DS3D_CHECK_AS(IoError, fs::is_regular_file(p, ec), kFn, ": missing list '", p.string(), "'");
    return detail::parse_tum_list(detail::read_text_file(p, kFn), p.string(), kFn, &duplicates);
  };
  std::vector<double> rgb_dup;
  std::vector<double> depth_dup;
  const auto rgb = read_list("rgb.txt", rgb_dup);
  const auto depth = read_list("depth.txt", depth_dup);

  RgbdDataset ds;
  ds.diagnostics_.rgb_duplicates = rgb_dup.size();
  ds.diagnostics_.first_rgb_duplicate = rgb_dup.empty() ? 0.0 : rgb_dup.front();
  ds.diagnostics_.depth_duplicates = depth_dup.size();
  ds.diagnostics_.first_depth_duplicate = depth_dup.empty() ? 0.0 : depth_dup.front();
  ds.dir_ = dir;
  if (options.camera) {
    options.camera->validate(kFn);
    ds.camera_ = *options.camera;
  } else if (fs::is_regular_file(dir / "camera.txt", ec)) {
    ds.camera_ = read_camera_file(dir / "camera.txt");
  } else {
    ds.camera_ = camera_without_file(dir);
  }
  std::vector<double> ts_rgb(rgb.size());
  std::vector<double> ts_depth(depth.size());
  for (std::size_t i = 0; i < rgb.size(); ++i) ts_rgb[i] = rgb[i].timestamp;
  for (std::size_t i = 0; i < depth.size(); ++i) ts_depth[i] = depth[i].timestamp;
  for (const auto& [i, j] :
       associate_timestamps(ts_rgb, ts_depth, options.offset, options.max_difference)) {
    ds.entries_.push_back(
        {rgb[i].timestamp, rgb[i].values.front(), depth[j].timestamp, depth[j].values.front()});
  }
  ds.diagnostics_.unassociated_rgb = rgb.size() - ds.entries_.size();
  find_gaps(ds.entries_, ds.diagnostics_);
  return ds;
}

std::size_t RgbdDataset::size() const { return entries_.size(); }

RgbdFrame RgbdDataset::frame(std::size_t i) const {
  constexpr const char* kFn = "ds3d::RgbdDataset::frame";
  DS3D_CHECK(i < entries_.size(), kFn, ": index ", i, " out of range (size ", entries_.size(), ")");
  const RgbdEntry& e = entries_[i];
  RgbdFrame f;
  f.index = i;
  f.timestamp = e.timestamp;
  f.depth_timestamp = e.depth_timestamp;
  const fs::path rgb_path = dir_ / e.rgb_file;
  const fs::path depth_path = dir_ / e.depth_file;
  for (const fs::path& p : {rgb_path, depth_path}) {
    DS3D_CHECK_AS(IoError, !is_truncated_jpeg(p), kFn, ": image '", p.string(),
                  "' is a truncated JPEG (no end-of-image marker FF D9 at its end)");
  }
  f.rgb = cv::imread(rgb_path.string(), cv::IMREAD_COLOR);
  DS3D_CHECK_AS(IoError, !f.rgb.empty(), kFn, ": cannot read rgb image '", rgb_path.string(), "'");
  f.depth = cv::imread(depth_path.string(), cv::IMREAD_UNCHANGED);
  DS3D_CHECK_AS(IoError, !f.depth.empty(), kFn, ": cannot read depth image '", depth_path.string(),
                "'");
  DS3D_CHECK_AS(IoError, f.depth.type() == CV_16UC1, kFn, ": depth image '", depth_path.string(),
                "' must be 16-bit single-channel (got ", f.depth.elemSize1() * 8, "-bit, ",
                f.depth.channels(), " channel(s)); an 8-bit depth image has lost its scale");
  DS3D_CHECK_AS(IoError, f.rgb.size() == f.depth.size(), kFn, ": rgb '", rgb_path.string(), "' is ",
                f.rgb.cols, "x", f.rgb.rows, " but depth '", depth_path.string(), "' is ",
                f.depth.cols, "x", f.depth.rows);
  return f;
}

const PinholeCamera& RgbdDataset::camera() const { return camera_; }

const fs::path& RgbdDataset::directory() const { return dir_; }

std::optional<fs::path> RgbdDataset::groundtruth_path() const {
  std::error_code ec;
  const fs::path p = dir_ / "groundtruth.txt";
  if (fs::is_regular_file(p, ec)) return p;
  return std::nullopt;
}

const std::vector<RgbdEntry>& RgbdDataset::entries() const { return entries_; }

}  // namespace ds3d
