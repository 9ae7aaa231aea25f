// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Ground truth and the TUM-layout writer: part locations, PNGs, lists, boxes.jsonl, groundtruth.
#include "ds3d/slam/synth.hpp"

#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <random>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "ds3d/detail/json.hpp"
#include "ds3d/detail/tum_text.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "synth_detections.hpp"

namespace ds3d::synth {

cv::Mat part_locations(const SynthFrame& frame, const PinholeCamera& camera) {
  DS3D_CHECK(frame.depth_true.type() == CV_32F && frame.human_id.type() == CV_8U &&
                 frame.depth_true.size() == frame.human_id.size(),
             "ds3d::synth::part_locations: frame lacks depth_true/human_id");
  cv::Mat out = cv::Mat::zeros(frame.depth_true.size(), CV_32FC3);
  for (int y = 0; y < out.rows; ++y) {
    for (int x = 0; x < out.cols; ++x) {
      const std::uint8_t h = frame.human_id.at<std::uint8_t>(y, x);
      const float z = frame.depth_true.at<float>(y, x);
      if (h == 0 || !(z > 0) || h > frame.boxes.size()) continue;
      const HumanBox& b = frame.boxes[h - 1U];
      const Eigen::Vector3d pw = frame.T_world_cam * camera.back_project(x, y, z);
      const Eigen::Vector3d local =
          Eigen::AngleAxisd(-b.yaw, Eigen::Vector3d::UnitZ()) * (pw - b.center);
      Eigen::Vector3d rel = (local.cwiseQuotient(b.size) + Eigen::Vector3d::Constant(0.5));
      rel = rel.cwiseMax(0.0).cwiseMin(1.0);
      out.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(rel.x()), static_cast<float>(rel.y()),
                                          static_cast<float>(rel.z()));
    }
  }
  return out;
}

namespace {

void write_png(const std::filesystem::path& p, const cv::Mat& img) {
  std::vector<std::uint8_t> buf;
  // Fast compression: the generator's time goes into rendering, not zlib.
  DS3D_CHECK_AS(IoError,
                cv::imencode(".png", img, buf,
                             {cv::IMWRITE_PNG_COMPRESSION, 1, cv::IMWRITE_PNG_STRATEGY,
                              cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY}),
                "ds3d::synth::generate_sequence: PNG encoding failed for '", p.string(), "'");
  detail::write_file_atomically(
      p, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()),
      "ds3d::synth::generate_sequence");
}

// CPU time of this thread: a shared, loaded machine inflates wall time, not CPU time.
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::string stamp_name(double t) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f", t);
  return buf;
}

std::string json_vec(const Eigen::Vector3d& v) {
  std::string out = "[";
  for (int k = 0; k < 3; ++k) {
    if (k > 0) out.push_back(',');
    out.append(detail::json_number(v[k]));
  }
  out.push_back(']');
  return out;
}

}  // namespace

namespace {

namespace fs = std::filesystem;
constexpr const char* kFn = "ds3d::synth::generate_sequence";

// A hidden sibling of `dir` that does not exist yet: ".NAME.TAG<random>".
fs::path sibling(const fs::path& dir, const char* tag) {
  thread_local std::mt19937_64 rng(std::random_device{}());
  std::error_code ec;
  for (;;) {
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on chained operator+ here.
    std::string name(1, '.');
    name.append(dir.filename().string());
    name.append(tag);
    name.append(std::to_string(rng() % 1000000000ULL));
    const fs::path p = dir.parent_path() / name;
    if (!fs::exists(p, ec)) return p;
  }
}

// Refuses a target that is a file, or a non-empty folder unless `overwrite`.
void check_target(const fs::path& out, bool overwrite) {
  std::error_code ec;
  if (!fs::exists(out, ec)) return;
  DS3D_CHECK_AS(IoError, fs::is_directory(out, ec), kFn, ": out_dir '", out.string(),
                "' exists and is not a folder");
  if (overwrite || fs::is_empty(out, ec)) return;
  std::size_t n = 0;
  std::string first;
  for (const auto& e : fs::directory_iterator(out, ec)) {
    if (n++ == 0) first = e.path().filename().string();
  }
  throw IoError(detail::concat(kFn, ": out_dir '", out.string(), "' is not empty (", n,
                               " entries, e.g. '", first,
                               "'); pass overwrite (ds3d-synth --overwrite) to replace it"));
}

// Moves the finished folder `tmp` to `out`; an earlier `out` is removed only after that.
void publish(const fs::path& tmp, const fs::path& out) {
  std::error_code ec;
  fs::path old;
  if (fs::exists(out, ec)) {
    if (fs::is_empty(out, ec)) {
      fs::remove(out, ec);
    } else {
      old = sibling(out, ".old");
      fs::rename(out, old, ec);
      DS3D_CHECK_AS(IoError, !ec, kFn, ": cannot move the earlier '", out.string(),
                    "' aside: ", ec.message());
    }
  }
  fs::rename(tmp, out, ec);
  if (ec) {
    std::error_code ec2;
    if (!old.empty()) fs::rename(old, out, ec2);  // put the earlier sequence back
    throw IoError(detail::concat(kFn, ": cannot rename '", tmp.string(), "' to '", out.string(),
                                 "': ", ec.message()));
  }
  if (!old.empty()) fs::remove_all(old, ec);
}

SynthSummary write_sequence(const fs::path& out_dir, const SynthOptions& options);

}  // namespace

SynthSummary generate_sequence(const std::filesystem::path& out_dir, const SynthOptions& options,
                               bool overwrite) {
  options.validate();
  fs::path out = out_dir.lexically_normal();
  if (!out.has_filename()) out = out.parent_path();  // "dir/" -> "dir"
  if (out.parent_path().empty()) out = fs::path(".") / out;
  check_target(out, overwrite);
  std::error_code ec;
  fs::create_directories(out.parent_path(), ec);
  const fs::path tmp = sibling(out, ".tmp");
  try {
    const SynthSummary sum = write_sequence(tmp, options);
    publish(tmp, out);
    return sum;
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

namespace {

SynthSummary write_sequence(const fs::path& out_dir, const SynthOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  const SyntheticScene scene(options);
  std::error_code ec;
  for (const char* sub : {"rgb", "depth", "mask"}) fs::create_directories(out_dir / sub, ec);
  if (options.write_parts) {
    fs::create_directories(out_dir / "parts", ec);
    fs::create_directories(out_dir / "parts_loc", ec);
  }
  DS3D_CHECK_AS(IoError, fs::is_directory(out_dir / "mask", ec),
                "ds3d::synth::generate_sequence: cannot create '", out_dir.string(), "'");
  SynthSummary sum;
  std::string rgb_txt = "# color images (ds3d synthetic, scenario " +
                        scenario_name(options.scenario) + ", seed " + std::to_string(options.seed) +
                        ")\n# timestamp filename\n";
  std::string depth_txt = "# depth maps (16-bit PNG, " +
                          detail::json_number(options.camera.depth_scale) +
                          " units per metre, 0 = no depth)\n# timestamp filename\n";
  std::string boxes;
  const bool noisy = options.detection_miss > 0 || options.detection_false > 0;
  NoisyDetections noisy_det(options);
  double render_s = 0;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const double t0 = thread_cpu_seconds();
    const SynthFrame f = scene.render(i);
    render_s += thread_cpu_seconds() - t0;
    const std::string name = stamp_name(f.timestamp);
    const std::string dname = stamp_name(f.timestamp + 0.0005);  // depth stamps differ slightly
    write_png(out_dir / "rgb" / (name + ".png"), f.rgb);
    write_png(out_dir / "depth" / (dname + ".png"), f.depth);
    write_png(out_dir / "mask" / (name + ".png"), f.dynamic_mask);
    if (options.write_parts) {
      cv::Mat parts;
      const cv::Mat zero = cv::Mat::zeros(f.part_id.size(), CV_8U);
      cv::merge(std::vector<cv::Mat>{f.human_id, f.part_id, zero}, parts);
      write_png(out_dir / "parts" / (name + ".png"), parts);
      cv::Mat loc;
      part_locations(f, options.camera).convertTo(loc, CV_16UC3, 65535.0);
      write_png(out_dir / "parts_loc" / (name + ".png"), loc);
    }
    rgb_txt += name + " rgb/" + name + ".png\n";
    depth_txt += dname + " depth/" + dname + ".png\n";
    boxes += "{\"timestamp\":" + name + ",\"frame\":" + std::to_string(i) + ",\"boxes\":[";
    for (std::size_t k = 0; k < f.boxes.size(); ++k) {
      const HumanBox& b = f.boxes[k];
      if (k > 0) boxes += ",";
      boxes += "{\"id\":" + std::to_string(b.id) + ",\"center\":" + json_vec(b.center) +
               ",\"size\":" + json_vec(b.size) + ",\"yaw\":" + detail::json_number(b.yaw) +
               ",\"sitting\":" + (b.sitting ? "true" : "false") +
               (is_crowd(options.scenario) ? ",\"carried\":" + std::to_string(b.carried) : "") +
               ",\"visible_pixels\":" + std::to_string(b.visible_pixels) + "}";
      sum.dynamic_pixels += static_cast<std::size_t>(b.visible_pixels);
    }
    boxes += "]}\n";
    if (noisy) noisy_det.add(f, name);
    ++sum.frames;
  }
  // Ground truth at 100 Hz over the sequence (the camera path is analytic), like TUM's mocap.
  Trajectory gt;
  const double t_end = scene.timestamp(scene.size() - 1) + 0.05;
  for (int k = 0;; ++k) {
    const double t = options.start_time - 0.05 + k * 0.01;
    if (t > t_end) break;
    gt.push_back({t, scene.camera_pose(t)});
  }
  const auto& c = options.camera;
  std::string cam = "# ds3d synthetic pinhole camera\n";
  for (const auto& [k, v] :
       std::vector<std::pair<std::string, double>>{{"fx", c.fx},
                                                   {"fy", c.fy},
                                                   {"cx", c.cx},
                                                   {"cy", c.cy},
                                                   {"k1", 0},
                                                   {"k2", 0},
                                                   {"p1", 0},
                                                   {"p2", 0},
                                                   {"k3", 0},
                                                   {"depth_scale", c.depth_scale},
                                                   {"width", c.width},
                                                   {"height", c.height}}) {
    cam += k + " " + detail::json_number(v) + "\n";
  }
  write_tum_trajectory(out_dir / "groundtruth.txt", gt);
  detail::write_file_atomically(out_dir / "camera.txt", cam, kFn);
  detail::write_file_atomically(out_dir / "boxes.jsonl", boxes, kFn);
  if (noisy)
    detail::write_file_atomically(out_dir / "detections_noisy.jsonl", noisy_det.text(), kFn);
  detail::write_file_atomically(out_dir / "depth.txt", depth_txt, kFn);
  detail::write_file_atomically(out_dir / "rgb.txt", rgb_txt, kFn);
  sum.render_seconds = render_s;
  sum.total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return sum;
}

}  // namespace

}  // namespace ds3d::synth
