// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-slam: runs the RGB-D SLAM front-end (include/ds3d/slam_frontend.hpp) on a TUM/Bonn folder.
// Usage: see --help. Exit codes: 0 ok, 1 runtime error, 2 bad usage.
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

// GCC 12 -O3 reports a false -Wrestrict inside std::string::insert as inlined into
// detail::write_file_atomically (trajectory.hpp); silence it for these headers only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wrestrict"
#include "ds3d/detail/json.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/slam/config.hpp"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/slam/slam_frontend.hpp"
#pragma GCC diagnostic pop
#include "ds3d/htx/weights_io.hpp"
#include "ds3d/version.hpp"
#include "ds3d_slam/dynamic_out.hpp"
#include "ds3d_slam/live_pacer.hpp"
#include "ds3d_slam/run_guard.hpp"

namespace {

constexpr const char* kUsage =
    "usage: ds3d-slam DATASET_DIR [--camera tum1|tum2|tum3|tum_ros|bonn|FILE] [--out traj.txt]\n"
    "                 [--dynamic none|geometric|htx|file:PATH|mask:DIR|A+B]\n"
    "                 [--gate none|motion|evidence] [--weights PATH] [--start-frame N]\n"
    "                 [--max-frames N] [--stats stats.json] [--viz OUT_DIR]\n"
    "                 [--dynamic-out DIR]\n"
    "                 [--keyframes kf.txt] [--map map.ply] [--config FILE] [--set KEY=VALUE]...\n"
    "                 [--realtime] [--quiet]\n"
    "       ds3d-slam [--config FILE] [--set KEY=VALUE]... --dump-config\n"
    "       ds3d-slam --help | --version\n"
    "Tracks an RGB-D sequence in TUM layout (rgb.txt, depth.txt) and writes one camera-to-world\n"
    "pose per frame in TUM format. With no --camera, DATASET_DIR/camera.txt is used if present,\n"
    "else the TUM/Bonn preset its folder name selects, else tum_ros (with a warning).\n"
    "--dynamic: where boxes of moving objects come from (key dynamic.source, default geometric):\n"
    "  none (keep every keypoint), geometric (multi-view motion, no learned weights), htx (the\n"
    "  HTx-lite 3-D detector on the preprocessed depth), file:PATH (JSON lines, see\n"
    "  detections.hpp), mask:DIR (one mask image per frame, named by its timestamp, non-zero =\n"
    "  dynamic; e.g. ds3d-synth's mask/ folder), or A+B: A, then B, each on the whole frame,\n"
    "  objects united (htx+geometric is 3DS-SLAM's semantic-then-geometric pair; with your own\n"
    "  detector, file:PATH+geometric). Keypoints in the boxes go through the box-gated HDBSCAN\n"
    "  filter (dynamic_filter.hpp).\n"
    "--gate (key dynamic.gate, default none): motion keeps the boxes only in frames where the\n"
    "  geometric source sees motion; evidence keeps a box while the geometric source's evidence\n"
    "  inside it is significant, and tracks it (docs/dynamic.md).\n"
    "Which --dynamic to use (README.md, \"Which --dynamic to use\"):\n"
    "  geometric (default)   people or objects may move; no weights, real time on 2 cores\n"
    "  none                  the scene is known to be static\n"
    "  htx+geometric         people may also stand or sit still (the detector sees them)\n"
    "  htx --gate motion     as htx, on real data, where the synthetic-only weights box furniture\n"
    "  file:PATH+geometric   you have your own detector; geometric covers what it misses\n"
    "--weights: HTx weights file (key dynamic.weights; default models/htx_lite_fast.safetensors\n"
    "  of the source tree, else <prefix>/share/ds3d/models/).\n"
    "--start-frame N: begin at frame N (0-based, of the associated rgb/depth pairs); --max-frames\n"
    "  then counts from there.\n"
    "--viz: one PNG per frame: tracked (green), dynamic (red), depth-edge (orange), other (grey)\n"
    "  keypoints, boxes (blue).\n"
    "--dynamic-out DIR: per frame, DIR/<timestamp>.png (8-bit, 255 = in a box the dynamic filter\n"
    "  processed or on the source's pixel mask) and one line of DIR/keypoints.jsonl (timestamp,\n"
    "  frame, mask, u, v, status: unmatched|tracked|dynamic|depth_edge per keypoint); see\n"
    "  docs/slam.md.\n"
    "--realtime: hand the frames over at the rate of their timestamps, as a live camera delivers\n"
    "  them (default: as fast as the pipeline takes them). A frame the pipeline is not ready for\n"
    "  is handed over late, never dropped: the trajectory is the same; --stats input_lag says how\n"
    "  late (docs/benchmarks.md).\n"
    "--config FILE: keys from a YAML or JSON file (nested `htx: {min_score: 0.4}` or dotted\n"
    "  `htx.min_score: 0.4`); --set KEY=VALUE overrides one key (repeatable; after --config,\n"
    "  in command-line order with --dynamic, --gate and --weights). --dump-config prints every\n"
    "  key with its value and help line as YAML and exits (docs/configuration.md).\n";

struct Args {
  std::filesystem::path dataset;
  std::string camera;
  std::filesystem::path out = "trajectory.txt";
  ds3d::slam::SlamConfig config;
  std::size_t start_frame = 0;
  std::size_t max_frames = 0;
  std::filesystem::path stats;
  std::filesystem::path viz;
  std::filesystem::path dynamic_out;
  std::filesystem::path keyframes;
  std::filesystem::path map;
  bool dump_config = false;
  bool realtime = false;
  bool quiet = false;
};

[[noreturn]] void usage_error(const std::string& msg) {
  std::cerr << "ds3d-slam: " << msg << "\n" << kUsage;
  std::exit(2);
}

std::size_t parse_count(const std::string& flag, const std::string& v) {
  std::size_t x = 0;
  const auto r = std::from_chars(v.data(), v.data() + v.size(), x);
  if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size()) {
    usage_error(flag + " expects an integer >= 0 (got '" + v + "')");
  }
  return x;
}

// --set KEY=VALUE, --dynamic, --gate and --weights in command-line order, after every --config.
void apply_settings(Args& a, const std::vector<std::filesystem::path>& files,
                    const std::vector<std::pair<std::string, std::string>>& sets) {
  try {
    for (const auto& f : files) ds3d::slam::apply_config_file(a.config, f);
    for (const auto& [k, v] : sets) a.config.set(k, v);
    a.config.validate();
  } catch (const ds3d::InvalidArgument& e) {
    usage_error(e.what());
  } catch (const ds3d::IoError& e) {
    usage_error(e.what());
  }
}

Args parse(int argc, char** argv) {
  Args a;
  std::vector<std::string> pos;
  std::vector<std::filesystem::path> files;
  std::vector<std::pair<std::string, std::string>> sets;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage_error(s + " needs a value");
      return argv[++i];
    };
    if (s == "-h" || s == "--help") {
      std::cout << kUsage;
      std::exit(0);
    } else if (s == "--version") {
      std::cout << "ds3d-slam " << ds3d::kVersion << "\n";
      std::exit(0);
    } else if (s == "--camera") {
      a.camera = value();
    } else if (s == "--out") {
      a.out = value();
    } else if (s == "--dynamic") {
      sets.emplace_back("dynamic.source", value());
    } else if (s == "--gate") {
      sets.emplace_back("dynamic.gate", value());
    } else if (s == "--weights") {
      sets.emplace_back("dynamic.weights", value());
      if (sets.back().second.empty()) usage_error("--weights needs a non-empty path");
    } else if (s == "--start-frame") {
      a.start_frame = parse_count(s, value());
    } else if (s == "--max-frames") {
      a.max_frames = parse_count(s, value());
    } else if (s == "--stats") {
      a.stats = value();
    } else if (s == "--viz") {
      a.viz = value();
    } else if (s == "--dynamic-out") {
      a.dynamic_out = value();
    } else if (s == "--keyframes") {
      a.keyframes = value();
    } else if (s == "--map") {
      a.map = value();
    } else if (s == "--config") {
      files.emplace_back(value());
    } else if (s == "--set") {
      const std::string kv = value();
      const auto eq = kv.find('=');
      if (eq == std::string::npos || eq == 0)
        usage_error("--set expects KEY=VALUE (got '" + kv + "')");
      sets.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    } else if (s == "--dump-config") {
      a.dump_config = true;
    } else if (s == "--realtime") {
      a.realtime = true;
    } else if (s == "--quiet") {
      a.quiet = true;
    } else if (!s.empty() && s[0] == '-') {
      usage_error("unknown option '" + s + "'");
    } else {
      pos.push_back(s);
    }
  }
  apply_settings(a, files, sets);
  if (a.dump_config) {
    std::cout << ds3d::slam::dump_config(a.config);
    std::exit(0);
  }
  if (pos.size() != 1) usage_error("expected exactly one DATASET_DIR");
  a.dataset = pos[0];
  return a;
}

struct Percentiles {
  double median = 0;
  double p95 = 0;
};
Percentiles percentiles(std::vector<double> v) {
  if (v.empty()) return {};
  std::sort(v.begin(), v.end());
  auto at = [&](double q) {
    const double pos = q * static_cast<double>(v.size() - 1);
    const auto lo = static_cast<std::size_t>(pos);
    const std::size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
  };
  return {at(0.5), at(0.95)};
}

void draw_viz(const std::filesystem::path& dir, const ds3d::RgbdDataset& ds,
              const ds3d::slam::TrackResult& r, const std::vector<ds3d::ImageBox>& boxes) {
  cv::Mat img = ds.frame(r.index).rgb.clone();
  for (const auto& b : boxes) {
    cv::rectangle(img, cv::Point2f(b.x_min, b.y_min), cv::Point2f(b.x_max, b.y_max),
                  cv::Scalar(255, 128, 0), 2, cv::LINE_AA);
  }
  for (std::size_t i = 0; i < r.keypoints.size(); ++i) {
    cv::Scalar c(128, 128, 128);
    if (r.keypoint_status[i] == ds3d::slam::KeypointStatus::kTracked) c = cv::Scalar(0, 200, 0);
    if (r.keypoint_status[i] == ds3d::slam::KeypointStatus::kDynamic) c = cv::Scalar(0, 0, 255);
    if (r.keypoint_status[i] == ds3d::slam::KeypointStatus::kDepthEdge) c = cv::Scalar(0, 200, 255);
    cv::circle(img, r.keypoints[i], 3, c, 1, cv::LINE_AA);
  }
  std::ostringstream label;
  label << "#" << r.index << " " << ds3d::slam::to_string(r.state) << " inliers " << r.num_inliers
        << (r.keyframe ? " KF" : "");
  cv::putText(img, label.str(), {8, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 255, 255), 1,
              cv::LINE_AA);
  char name[32];
  std::snprintf(name, sizeof(name), "frame_%06zu.png", r.index);
  const auto path = dir / name;
  DS3D_CHECK_AS(ds3d::IoError, cv::imwrite(path.string(), img), "cannot write ", path.string());
}

// Light per-frame record for --stats (the full TrackResult holds keypoints).
struct FrameRecord {
  bool tracked = false;
  ds3d::slam::TrackState state = ds3d::slam::TrackState::kNotInitialized;
  ds3d::slam::StageTimes times;
  int features = 0;    // TrackResult::num_features
  int dynamic = 0;     // num_dynamic
  int refilled = 0;    // num_refilled
  int inliers = 0;     // num_inliers
  int depth_edge = 0;  // num_depth_edge
  bool keyframe = false;
  bool odometry = false;
  bool motion_gated = false;
  double interval_ms = 0;  // wall time since the previous pose out (the first: since the start)
  double latency_ms = 0;   // wall time to pose out from the frame read (decoded), or with
                           // --realtime from when a live camera would have delivered it

  static FrameRecord of(const ds3d::slam::TrackResult& r) {
    return {r.tracked,     r.state,        r.times,       r.num_features,
            r.num_dynamic, r.num_refilled, r.num_inliers, r.num_depth_edge,
            r.keyframe,    r.odometry,     r.motion_gated};
  }
};

// Why the run ended before the last requested frame ("" = it did not).
struct StopInfo {
  std::string reason;   // "frame error", "SIGINT", "SIGTERM", "error"
  std::string message;  // the error, for frame and other errors
  int signal = 0;
  [[nodiscard]] bool stopped() const { return !reason.empty(); }
};

// Per-frame counts of the run (--stats "per_frame", one array entry per frame) and their totals.
void write_per_frame(std::ostream& js, const std::vector<FrameRecord>& results) {
  using R = FrameRecord;
  long long features = 0;
  long long dynamic = 0;
  for (const auto& r : results) {
    features += r.features;
    dynamic += r.dynamic;
  }
  const double fraction =
      features > 0 ? static_cast<double>(dynamic) / static_cast<double>(features) : 0.0;
  js << "  \"totals\": {\"features\": " << features << ", \"dynamic\": " << dynamic
     << ", \"dynamic_fraction\": " << ds3d::detail::json_number(fraction)
     << "},\n  \"per_frame\": {\n    \"state\": [";
  for (std::size_t i = 0; i < results.size(); ++i) {
    js << (i > 0 ? ", \"" : "\"") << ds3d::slam::to_string(results[i].state) << "\"";
  }
  js << "]";
  const std::vector<std::pair<const char*, int (*)(const R&)>> columns{
      {"features", [](const R& r) { return r.features; }},
      {"dynamic", [](const R& r) { return r.dynamic; }},
      {"refilled", [](const R& r) { return r.refilled; }},
      {"inliers", [](const R& r) { return r.inliers; }},
      {"depth_edge", [](const R& r) { return r.depth_edge; }},
      {"keyframe", [](const R& r) { return r.keyframe ? 1 : 0; }},
      {"odometry", [](const R& r) { return r.odometry ? 1 : 0; }},
      {"motion_gated", [](const R& r) { return r.motion_gated ? 1 : 0; }}};
  for (const auto& [name, get] : columns) {
    js << ",\n    \"" << name << "\": [";
    for (std::size_t i = 0; i < results.size(); ++i) js << (i > 0 ? ", " : "") << get(results[i]);
    js << "]";
  }
  const std::vector<std::pair<const char*, double (*)(const R&)>> times{
      {"interval_ms", [](const R& r) { return r.interval_ms; }},
      {"latency_ms", [](const R& r) { return r.latency_ms; }},
      {"extract_ms", [](const R& r) { return r.times.extract_ms; }},
      {"detect_ms", [](const R& r) { return r.times.detect_ms; }},
      {"track_ms", [](const R& r) { return r.times.track_ms; }},
      {"track_cpu_ms", [](const R& r) { return r.times.track_cpu_ms; }}};
  for (const auto& [name, get] : times) {
    js << ",\n    \"" << name << "\": [";
    for (std::size_t i = 0; i < results.size(); ++i) {
      js << (i > 0 ? ", " : "") << ds3d::detail::json_number(get(results[i]));
    }
    js << "]";
  }
  js << "\n  }\n";
}

// --realtime: how late the frames were handed over [ms] (median, p95, max); null without it.
std::string input_lag_json(bool realtime, const std::vector<double>& lag_ms) {
  if (!realtime) return "null";
  const auto p = percentiles(lag_ms);
  const double max = lag_ms.empty() ? 0.0 : *std::max_element(lag_ms.begin(), lag_ms.end());
  using ds3d::detail::json_number;
  return "{\"median_ms\": " + json_number(p.median) + ", \"p95_ms\": " + json_number(p.p95) +
         ", \"max_ms\": " + json_number(max) + "}";
}

// Prints the one-line summary (unless --quiet) and returns the --stats JSON.
std::string report_run(const Args& a, const ds3d::slam::SlamFrontend& slam,
                       const std::vector<FrameRecord>& results, const std::vector<double>& lag_ms,
                       double wall_s, std::size_t total, const StopInfo& stop,
                       const ds3d_slam_tool::InputWarnings& warn) {
  const ds3d::slam::SlamConfig& c = a.config;
  std::size_t tracked = 0;
  std::size_t lost = 0;
  std::size_t relocalized = 0;
  std::vector<double> ex;
  std::vector<double> de;
  std::vector<double> pr;
  std::vector<double> fi;
  std::vector<double> tr;
  std::vector<double> ex_cpu;
  std::vector<double> tr_cpu;
  std::vector<double> de_cpu;
  std::vector<double> pr_cpu;
  std::vector<double> frame_ms;    // wall time between consecutive outputs
  std::vector<double> latency_ms;  // the frames whose read time was known
  for (const auto& r : results) {
    frame_ms.push_back(r.interval_ms);
    if (std::isfinite(r.latency_ms)) latency_ms.push_back(r.latency_ms);
    ex_cpu.push_back(r.times.extract_cpu_ms);
    tr_cpu.push_back(r.times.track_cpu_ms);
    de_cpu.push_back(r.times.detect_cpu_ms);
    pr_cpu.push_back(r.times.prepare_cpu_ms);
    tracked += r.tracked ? 1 : 0;
    lost += r.state == ds3d::slam::TrackState::kLost ? 1 : 0;
    relocalized += r.state == ds3d::slam::TrackState::kRelocalized ? 1 : 0;
    ex.push_back(r.times.extract_ms);
    de.push_back(r.times.detect_ms);
    pr.push_back(r.times.prepare_ms);
    fi.push_back(r.times.filter_ms);
    tr.push_back(r.times.track_ms);
  }
  // The first frames include thread start-up; fps is over the steady state (all intervals but
  // the first) so that it reflects the pipeline's throughput.
  std::vector<double> fps;
  for (std::size_t i = 1; i < frame_ms.size(); ++i)
    fps.push_back(frame_ms[i] > 0 ? 1000.0 / frame_ms[i] : 0.0);
  const auto fps_p = percentiles(fps);
  const auto interval_p = percentiles(frame_ms);
  const auto latency_p = percentiles(latency_ms);
  using ds3d::detail::json_escape;
  using ds3d::detail::json_number;
  std::ostringstream js;
  auto stage = [&](const char* name, const std::vector<double>& v, bool comma) {
    const auto p = percentiles(v);
    js << "    \"" << json_escape(name) << "\""
       << ": {\"median_ms\": " << json_number(p.median) << ", \"p95_ms\": " << json_number(p.p95)
       << "}" << (comma ? ",\n" : "\n");
  };
  js << "{\n  \"dataset\": \"" << json_escape(a.dataset.string()) << "\",\n"
     << "  \"dynamic\": \"" << json_escape(c.dynamic) << "\",\n"
     << "  \"gate\": \"" << ds3d::slam::to_string(c.gate) << "\",\n"
     << "  \"detect_every\": " << c.htx.detect_every << ",\n"
     << "  \"frames\": " << results.size() << ",\n"
     << "  \"frames_requested\": " << total << ",\n"
     << "  \"stopped_early\": " << (stop.stopped() ? "true" : "false") << ",\n"
     << "  \"stop_reason\": \"" << json_escape(stop.reason) << "\",\n"
     << "  \"stop_message\": \"" << json_escape(stop.message) << "\",\n"
     << "  \"input_warnings\": {\"duplicate_rgb_stamps\": " << warn.duplicate_rgb_stamps
     << ", \"duplicate_depth_stamps\": " << warn.duplicate_depth_stamps
     << ", \"unassociated_rgb\": " << warn.unassociated_rgb
     << ", \"large_gaps\": " << warn.large_gaps
     << ", \"frames_without_detections\": " << warn.frames_without_detections
     << ", \"weights_without_checksum\": " << warn.weights_without_checksum << "},\n"
     << "  \"tracked_frames\": " << tracked << ",\n"
     << "  \"lost_frames\": " << lost << ",\n"
     << "  \"relocalized_frames\": " << relocalized << ",\n"
     << "  \"keyframes\": " << slam.num_keyframes() << ",\n"
     << "  \"culled_keyframes\": " << slam.culled_keyframes().size() << ",\n"
     << "  \"merged_segments\": " << slam.merged_segments() << ",\n"
     << "  \"interpolated_frames\": " << slam.interpolated_frames() << ",\n"
     << "  \"map_points\": " << slam.map_points().rows() << ",\n"
     << "  \"threaded\": " << (c.pipeline.threaded ? "true" : "false") << ",\n"
     << "  \"realtime\": " << (a.realtime ? "true" : "false") << ",\n"
     << "  \"wall_s\": " << json_number(wall_s) << ",\n"
     << "  \"fps_mean\": " << json_number(static_cast<double>(results.size()) / wall_s) << ",\n"
     << "  \"fps_median\": " << json_number(fps_p.median) << ",\n"
     << "  \"frame_interval\": {\"median_ms\": " << json_number(interval_p.median)
     << ", \"p95_ms\": " << json_number(interval_p.p95) << "},\n"
     << "  \"latency\": {\"median_ms\": " << json_number(latency_p.median)
     << ", \"p95_ms\": " << json_number(latency_p.p95) << "},\n"
     << "  \"input_lag\": " << input_lag_json(a.realtime, lag_ms) << ",\n"
     << "  \"local_ba\": {\"count\": " << slam.num_local_ba()
     << ", \"total_cpu_ms\": " << json_number(slam.local_ba_ms()) << ", \"mean_cpu_ms\": "
     << json_number(slam.num_local_ba() > 0
                        ? slam.local_ba_ms() / static_cast<double>(slam.num_local_ba())
                        : 0.0)
     << "},\n  \"refine_cpu_ms\": " << json_number(slam.refine_ms()) << ",\n  \"stages\": {\n";
  stage("extract", ex, true);
  stage("detect", de, true);
  stage("prepare", pr, true);
  stage("filter", fi, true);
  stage("track", tr, false);
  js << "  },\n  \"stages_cpu\": {\n";
  stage("extract", ex_cpu, true);
  stage("detect", de_cpu, true);
  stage("prepare", pr_cpu, true);
  stage("track", tr_cpu, false);
  js << "  },\n";
  write_per_frame(js, results);
  js << "}\n";
  if (!a.quiet) {
    std::cout << "frames " << results.size() << ", tracked " << tracked << ", lost " << lost
              << ", keyframes " << slam.num_keyframes() << ", map points "
              << slam.map_points().rows() << ", " << static_cast<double>(results.size()) / wall_s
              << " fps (median " << fps_p.median << ")";
    if (a.realtime) std::cout << ", input lag p95 " << percentiles(lag_ms).p95 << " ms";
    if (slam.merged_segments() > 0 || slam.interpolated_frames() > 0) {
      std::cout << ", re-anchored segments merged " << slam.merged_segments()
                << ", lost frames interpolated " << slam.interpolated_frames();
    }
    std::cout << "\n";
  }
  return js.str();
}

// Trajectory, keyframes, map and stats: each written atomically (temporary file, fsync, rename).
void write_outputs(const Args& a, const ds3d::slam::SlamFrontend& slam, const std::string& stats) {
  ds3d::write_tum_trajectory(a.out, ds3d::slam::to_trajectory(slam.trajectory()));
  if (!a.keyframes.empty()) {
    ds3d::write_tum_trajectory(a.keyframes, ds3d::slam::to_trajectory(slam.keyframe_trajectory()));
  }
  if (!a.map.empty()) slam.write_map_ply(a.map);
  if (!a.stats.empty()) ds3d::detail::write_file_atomically(a.stats, stats, "--stats");
}

// A warning when the htx weights carry no checksum (older exports); nothing to check then.
std::size_t warn_unchecked_weights(const ds3d::slam::SlamConfig& c) {
  const auto path = ds3d_slam_tool::htx_weights(c);
  if (path.empty() || ds3d::WeightsFile::read(path).has_checksum()) return 0;
  std::cerr << "ds3d-slam: warning: weights '" << path.string()
            << "' carry no tensors_sha256 checksum (exported before checksums); their values "
               "were range-checked only\n";
  return 1;
}

int run(const Args& a) {
  const ds3d::slam::SlamConfig& c = a.config;
  // Outputs first: a missing or read-only folder fails before any weights or image is read.
  ds3d_slam_tool::check_output_paths(
      {{"--out", a.out}, {"--stats", a.stats}, {"--keyframes", a.keyframes}, {"--map", a.map}},
      {{"--viz", a.viz}, {"--dynamic-out", a.dynamic_out}});
  // The source next: a bad --dynamic or --weights fails before any image is read.
  std::shared_ptr<ds3d::slam::DynamicObjectSource> source;
  try {
    source = ds3d::slam::make_dynamic_source(c);
  } catch (const ds3d::InvalidArgument& e) {
    usage_error(e.what());
  }
  ds3d::DatasetOptions dopt;
  if (!a.camera.empty()) {
    const bool preset = a.camera == "tum1" || a.camera == "tum2" || a.camera == "tum3" ||
                        a.camera == "tum_ros" || a.camera == "bonn";
    dopt.camera = preset ? ds3d::camera_preset(a.camera) : ds3d::read_camera_file(a.camera);
  }
  const auto ds = ds3d::RgbdDataset::open(a.dataset, dopt);
  DS3D_CHECK_AS(ds3d::IoError, ds.size() > 0, "no associated rgb/depth pairs in ",
                a.dataset.string());
  if (a.start_frame >= ds.size()) {
    usage_error("--start-frame " + std::to_string(a.start_frame) + " is past the last frame: " +
                a.dataset.string() + " has " + std::to_string(ds.size()) +
                " associated frames (0-based, so at most " + std::to_string(ds.size() - 1) + ")");
  }
  const std::size_t left = ds.size() - a.start_frame;
  const std::size_t total = a.max_frames == 0 ? left : std::min(a.max_frames, left);
  const std::size_t end = a.start_frame + total;  // one past the last frame run
  auto input_warnings = ds3d_slam_tool::check_inputs(ds, a.start_frame, total, c);
  input_warnings.weights_without_checksum = warn_unchecked_weights(c);
  cv::setNumThreads(c.cv_threads);

  ds3d::slam::FrontendConfig cfg = c.frontend;
  cfg.camera = ds.camera();
  std::shared_ptr<ds3d_slam_tool::RecordingMasker> masker;
  if (c.dynamic != "none") {
    masker = std::make_shared<ds3d_slam_tool::RecordingMasker>(c.filter);
    masker->set_record(!a.viz.empty(), !a.dynamic_out.empty());
  }
  std::optional<ds3d_slam_tool::DynamicOutWriter> dynamic_out;
  if (!a.dynamic_out.empty()) dynamic_out.emplace(a.dynamic_out, ds);
  ds3d::slam::SlamFrontend slam(cfg, source, masker);

  const bool tty = !a.quiet && isatty(fileno(stderr)) != 0;
  std::mutex read_mutex;  // read_at: written by the reader thread
  std::unordered_map<std::size_t, std::chrono::steady_clock::time_point> read_at;
  std::vector<FrameRecord> results;
  auto last = std::chrono::steady_clock::now();
  const auto t_start = last;
  std::size_t done = 0;
  const auto on_result = [&](const ds3d::slam::TrackResult& r) {
    const auto now = std::chrono::steady_clock::now();
    const double interval = std::chrono::duration<double, std::milli>(now - last).count();
    last = now;
    double latency = std::numeric_limits<double>::quiet_NaN();
    {
      const std::lock_guard<std::mutex> lock(read_mutex);
      const auto it = read_at.find(r.index);
      if (it != read_at.end()) {
        latency = std::chrono::duration<double, std::milli>(now - it->second).count();
        read_at.erase(it);
      }
    }
    ++done;
    results.push_back(FrameRecord::of(r));
    results.back().interval_ms = interval;
    results.back().latency_ms = latency;
    if (!a.viz.empty() || dynamic_out) {
      const auto rec = masker ? masker->take(r.index) : ds3d_slam_tool::DynamicRecord{};
      if (!a.viz.empty()) draw_viz(a.viz, ds, r, rec.boxes);
      if (dynamic_out) dynamic_out->write(r, rec.mask);
    }
    if (tty && (done % 5 == 0 || done == total)) {
      const double sec = std::chrono::duration<double>(now - t_start).count();
      const int width = 30;
      const auto filled =
          static_cast<int>(width * static_cast<double>(done) / static_cast<double>(total));
      std::fprintf(stderr, "\r[%s%s] %zu/%zu frames  %.1f fps  %s   ",
                   std::string(static_cast<std::size_t>(filled), '#').c_str(),
                   std::string(static_cast<std::size_t>(width - filled), '.').c_str(), done, total,
                   sec > 0 ? static_cast<double>(done) / sec : 0.0, ds3d::slam::to_string(r.state));
      std::fflush(stderr);
    }
  };
  // Frames are read here (not by run_dataset) so that an unreadable frame or a stop signal ends
  // the input: the frames read so far are still tracked, finished and written.
  StopInfo stop;
  ds3d_slam_tool::LivePacer pacer;  // --realtime
  const auto stop_requested = [] { return ds3d_slam_tool::stop_signal() != 0; };
  std::size_t next_index = a.start_frame;
  const auto next = [&]() -> std::optional<ds3d::slam::FrameInput> {
    if (next_index >= end || stop_requested()) return std::nullopt;
    ds3d::RgbdFrame f;
    try {
      f = ds.frame(next_index);
    } catch (const ds3d::IoError& e) {
      if (ds3d_slam_tool::stop_signal() == 0) {  // else the stop request is the reason
        stop.reason = "frame error";
        stop.message = e.what();
      }
      return std::nullopt;
    }
    // --realtime: the latency counts from when a live camera would have delivered the frame; a
    // stop request while waiting for it ends the input before it.
    const auto delivered =
        a.realtime ? pacer.wait(f.timestamp, stop_requested) : std::chrono::steady_clock::now();
    if (stop_requested()) return std::nullopt;
    ++next_index;
    ds3d::slam::FrameInput in = ds3d::slam::to_frame_input(std::move(f));
    const std::lock_guard<std::mutex> lock(read_mutex);
    read_at[in.index] = delivered;
    return in;
  };
  ds3d_slam_tool::install_stop_handler();
  try {
    (void)ds3d::slam::run_pipeline(slam, next, on_result, c.pipeline);
  } catch (const std::exception& e) {
    stop.reason = "error";
    stop.message = e.what();
  }
  if (tty) std::fprintf(stderr, "\n");
  if (stop.reason.empty() && ds3d_slam_tool::stop_signal() != 0 && next_index < end) {
    stop.signal = ds3d_slam_tool::stop_signal();
    stop.reason = ds3d_slam_tool::signal_name(stop.signal);
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  if (!stop.message.empty()) std::cerr << "ds3d-slam: " << stop.message << "\n";
  write_outputs(a, slam,
                report_run(a, slam, results, pacer.lag_ms(), wall_s, total, stop, input_warnings));
  if (stop.stopped()) {
    std::cerr << "ds3d-slam: stopped early (" << stop.reason << ") after " << results.size()
              << " of " << total << " frames; the trajectory of the frames tracked so far is in "
              << a.out.string() << "\n";
  } else if (!a.quiet) {
    std::cout << "trajectory written to " << a.out.string() << "\n";
  }
  if (stop.signal != 0) return 128 + stop.signal;
  return stop.stopped() ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
  try {
    return run(a);
  } catch (const std::exception& e) {
    std::cerr << "ds3d-slam: " << e.what() << "\n";
    return 1;
  }
}
