// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-slam: runs the RGB-D SLAM front-end (include/ds3d/slam_frontend.hpp) on a TUM/Bonn folder.
// Usage: see --help. Exit codes: 0 ok, 1 runtime error, 2 bad usage.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

// GCC 12 -O3 reports a false -Wrestrict inside std::string::insert as inlined into
// detail::write_file_atomically (trajectory.hpp); silence it for these headers only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wrestrict"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/detail/json.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/slam/slam_frontend.hpp"
#include "ds3d/eval/trajectory.hpp"
#pragma GCC diagnostic pop

namespace {

constexpr const char* kUsage =
    "usage: ds3d-slam DATASET_DIR [--camera tum1|tum2|tum3|tum_ros|bonn|FILE] [--out traj.txt]\n"
    "                 [--dynamic none|geometric|htx|htx+geometric|htx&geometric|htx&&geometric|\n"
    "                            file:PATH]\n"
    "                 [--weights PATH]\n"
    "                 [--detect-every K] [--min-score S] [--hold-frames K] [--floor]\n"
    "                 [--no-segment] [--segment-frames K]\n"
    "                 [--segment-boxes-only] [--max-frames N]\n"
    "                 [--stats "
    "stats.json] "
    "[--viz OUT_DIR]\n"
    "                 [--keyframes kf.txt] [--map map.ply] [--no-threads] [--no-local-ba]\n"
    "                 [--fusion] [--local-window N] [--bf BF] [--kf-ratio R]\n"
    "                 [--cull-keyframes | --no-cull-keyframes] [--kf-redundancy R]\n"
    "                 [--no-refine] [--refine-rounds N] [--cv-threads N] [--quiet]\n"
    "Tracks an RGB-D sequence in TUM layout (rgb.txt, depth.txt) and writes one camera-to-world\n"
    "pose per frame in TUM format. With no --camera, DATASET_DIR/camera.txt is used if present.\n"
    "--dynamic: where boxes of moving objects come from: none (keep every keypoint), geometric\n"
    "  (multi-view motion, no learned weights), htx (the HTx-lite 3-D detector on the "
    "preprocessed\n"
    "  depth), file:PATH (JSON lines, see detections.hpp), or A+B: A, then B on what A left\n"
    "  (htx+geometric is 3DS-SLAM's semantic-then-geometric order), or A&B: A's boxes only where\n"
    "  B sees motion in the frame (htx&geometric: detected people that move), or A&&geometric:\n"
    "  A's boxes where the geometric source's raw evidence inside them is significant, tracked\n"
    "  while they stay (MotionGateParams::evidence, docs/dynamic.md); keypoints in the boxes go\n"
    "  through the box-gated HDBSCAN filter (dynamic_filter.hpp).\n"
    "--weights: HTx weights file (default: models/htx_lite_fast.safetensors of the source tree,\n"
    "  else <prefix>/share/ds3d/models/). --detect-every K: run the detector on every K-th frame\n"
    "  (default 1; the frames between reuse its boxes). --min-score S: detector score threshold\n"
    "  in [0, 1] (default 0.3). --hold-frames K: carry a box the detector missed up to K frames\n"
    "  while its part head still sees foreground in it (default 10, 0 = off). --floor:\n"
    "  keypoints on the floor plane that the detector's preprocessing finds stay static\n"
    "  (HtxSourceParams::report_floor; off by default, see docs/dynamic.md: better precision on\n"
    "  synthetic scenes, fewer person keypoints removed on recorded ones). --no-segment: do\n"
    "  not confirm the detector's boxes with its part head's foreground points\n"
    "  (HtxSourceParams::segment, on by default).\n"
    "  --segment-frames K: average each point's part-head logit with its nearest point's (within\n"
    "  one voxel) in each of the last K frames (default 10, 0 = off). --segment-boxes-only: the\n"
    "  part head decides inside the boxes only (by default it also marks the keypoints it sees on\n"
    "  people outside them). Both: docs/dynamic.md.\n"
    "--viz: one JPEG per frame: tracked (green), dynamic (red), other (grey) keypoints, boxes "
    "(blue).\n"
    "--fusion: merge duplicate map points with covisible keyframes (ORB-SLAM2's Fuse; off by\n"
    "  default: it hurts on dynamic scenes without a dynamic filter, see docs/slam.md).\n"
    "--local-window: keyframes optimised by local BA (default 10).\n"
    "--bf: virtual stereo baseline × fx for the depth residual [px·m] (default 40, ORB-SLAM2's).\n"
    "--kf-ratio: keyframe when fewer than this fraction of the reference keyframe's points are\n"
    "  tracked (default 0.75, ORB-SLAM2's RGB-D value), in (0, 1].\n"
    "--cull-keyframes / --no-cull-keyframes: remove redundant keyframes (ORB-SLAM2's\n"
    "  KeyFrameCulling: > R of their close points seen by >= 3 other keyframes at the same or a\n"
    "  finer scale; default on, see docs/slam.md). --kf-redundancy R: that ratio (default 0.9),\n"
    "  in (0, 1].\n"
    "--no-refine: keep the tracked poses (by default, after the final global BA each non-keyframe\n"
    "  pose is re-optimised against the final map). --refine-rounds N: then N rounds of (update\n"
    "  every map point from all frames' matches; re-optimise the frames) (default 2).\n"
    "--cv-threads: OpenCV's own worker threads (default 1: the pipeline stages are the threads).\n";

struct Args {
  std::filesystem::path dataset;
  std::string camera;
  std::filesystem::path out = "trajectory.txt";
  std::string dynamic = "none";
  std::filesystem::path weights;
  int detect_every = 1;
  float min_score = -1.0F;  // < 0 = the HtxSourceParams default
  int hold_frames = -1;     // < 0 = the HtxSourceParams default
  int segment_frames = -1;  // < 0 = the HtxSourceParams default
  bool floor = false;
  bool no_segment = false;
  bool segment_boxes_only = false;
  std::size_t max_frames = 0;
  std::filesystem::path stats;
  std::filesystem::path viz;
  std::filesystem::path keyframes;
  std::filesystem::path map;
  bool threads = true;
  bool local_ba = true;
  bool fusion = false;
  int local_window = 0;      // 0 = the FrontendConfig default
  double bf = 0;             // 0 = the FrontendConfig default
  double kf_ratio = 0;       // 0 = the FrontendConfig default
  int cull_keyframes = -1;   // < 0 = the FrontendConfig default, else 0/1
  double kf_redundancy = 0;  // 0 = the FrontendConfig default
  bool refine = true;
  int refine_rounds = -1;  // < 0 = the FrontendConfig default
  int cv_threads = 1;
  bool quiet = false;
};

[[noreturn]] void usage_error(const std::string& msg) {
  std::cerr << "ds3d-slam: " << msg << "\n" << kUsage;
  std::exit(2);
}

long parse_int(const std::string& flag, const std::string& v, long lo) {
  char* end = nullptr;
  const long x = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || end == nullptr || *end != '\0' || x < lo) {
    std::ostringstream msg;
    msg << flag << " expects an integer >= " << lo << " (got '" << v << "')";
    usage_error(msg.str());
  }
  return x;
}

// A ratio in (0, 1]; anything else is a usage error naming the flag and the value.
double parse_fraction(const std::string& flag, const std::string& v) {
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0' || !(x > 0 && x <= 1)) {
    usage_error(flag + " expects a number in (0, 1] (got '" + v + "')");
  }
  return x;
}

// A finite number in [lo, hi]; anything else is a usage error naming the flag, `range` (the
// accepted values in words) and the value.
float parse_float(const std::string& flag, const std::string& v, float lo, float hi,
                  const std::string& range) {
  char* end = nullptr;
  const float x = std::strtof(v.c_str(), &end);
  if (v.empty() || *end != '\0' || !std::isfinite(x) || !(x >= lo && x <= hi)) {
    usage_error(flag + " expects " + range + " (got '" + v + "')");
  }
  return x;
}

Args parse(int argc, char** argv) {
  Args a;
  std::vector<std::string> pos;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage_error(s + " needs a value");
      return argv[++i];
    };
    if (s == "-h" || s == "--help") {
      std::cout << kUsage;
      std::exit(0);
    } else if (s == "--camera") {
      a.camera = value();
    } else if (s == "--out") {
      a.out = value();
    } else if (s == "--dynamic") {
      a.dynamic = value();
    } else if (s == "--weights") {
      a.weights = value();
      if (a.weights.empty()) usage_error("--weights needs a non-empty path");
    } else if (s == "--detect-every") {
      a.detect_every = static_cast<int>(parse_int(s, value(), 1));
    } else if (s == "--min-score") {
      a.min_score = parse_float(s, value(), 0.0F, 1.0F, "a number in [0, 1]");
    } else if (s == "--hold-frames") {
      a.hold_frames = static_cast<int>(parse_int(s, value(), 0));
    } else if (s == "--segment-frames") {
      a.segment_frames = static_cast<int>(parse_int(s, value(), 0));
    } else if (s == "--floor") {
      a.floor = true;
    } else if (s == "--no-segment") {
      a.no_segment = true;
    } else if (s == "--segment-boxes-only") {
      a.segment_boxes_only = true;
    } else if (s == "--max-frames") {
      a.max_frames = static_cast<std::size_t>(parse_int(s, value(), 0));
    } else if (s == "--stats") {
      a.stats = value();
    } else if (s == "--viz") {
      a.viz = value();
    } else if (s == "--keyframes") {
      a.keyframes = value();
    } else if (s == "--map") {
      a.map = value();
    } else if (s == "--no-threads") {
      a.threads = false;
    } else if (s == "--no-local-ba") {
      a.local_ba = false;
    } else if (s == "--fusion") {
      a.fusion = true;
    } else if (s == "--bf") {
      a.bf = std::stod(value());
    } else if (s == "--kf-ratio") {
      a.kf_ratio = parse_fraction(s, value());
    } else if (s == "--cull-keyframes") {
      a.cull_keyframes = 1;
    } else if (s == "--no-cull-keyframes") {
      a.cull_keyframes = 0;
    } else if (s == "--kf-redundancy") {
      a.kf_redundancy = parse_fraction(s, value());
    } else if (s == "--refine-rounds") {
      a.refine_rounds = static_cast<int>(parse_int(s, value(), 0));
    } else if (s == "--no-refine") {
      a.refine = false;
    } else if (s == "--local-window") {
      a.local_window = static_cast<int>(parse_int(s, value(), 2));
    } else if (s == "--cv-threads") {
      a.cv_threads = static_cast<int>(parse_int(s, value(), 0));
    } else if (s == "--quiet") {
      a.quiet = true;
    } else if (!s.empty() && s[0] == '-') {
      usage_error("unknown option '" + s + "'");
    } else {
      pos.push_back(s);
    }
  }
  if (pos.size() != 1) usage_error("expected exactly one DATASET_DIR");
  a.dataset = pos[0];
  const bool uses_htx =
      a.dynamic.rfind("file:", 0) != 0 && a.dynamic.find("htx") != std::string::npos;
  if (!uses_htx &&
      (!a.weights.empty() || a.detect_every != 1 || a.min_score >= 0.0F || a.floor ||
       a.no_segment || a.hold_frames >= 0 || a.segment_frames >= 0 || a.segment_boxes_only)) {
    usage_error(
        "--weights, --detect-every, --min-score, --hold-frames, --floor, --no-segment, "
        "--segment-frames and --segment-boxes-only need --dynamic htx or htx+...");
  }
  if (a.no_segment && (a.segment_frames > 0 || a.segment_boxes_only)) {
    usage_error(
        "--segment-frames and --segment-boxes-only act on the part head's segmentation: not "
        "with --no-segment");
  }
  if (a.hold_frames >= 0 && a.dynamic.find("&&") != std::string::npos) {
    usage_error("--hold-frames has no effect with --dynamic A&&geometric (its tracks hold boxes)");
  }
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

// The HDBSCAN masker, remembering each frame's boxes for --viz (the masker runs in the filter
// stage's thread, the drawing on the caller's).
class RecordingMasker final : public ds3d::slam::DynamicFeatureMasker {
 public:
  std::vector<std::uint8_t> mask(const ds3d::slam::FrameInput& frame,
                                 const ds3d::PinholeCamera& camera,
                                 const ds3d::slam::OrbFeatures& features,
                                 const ds3d::slam::DynamicObjects& objects) override {
    auto m = inner_.mask(frame, camera, features, objects);
    if (record_) {
      std::vector<ds3d::ImageBox> boxes;
      for (const auto& b : inner_.last_result().boxes) boxes.push_back(b.box);
      const std::lock_guard<std::mutex> lock(mutex_);
      boxes_[frame.index] = std::move(boxes);
    }
    return m;
  }
  [[nodiscard]] std::string name() const override { return inner_.name(); }
  void set_record(bool on) { record_ = on; }
  std::vector<ds3d::ImageBox> take(std::size_t index) {
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto it = boxes_.find(index);
    if (it == boxes_.end()) return {};
    auto out = std::move(it->second);
    boxes_.erase(it);
    return out;
  }

 private:
  ds3d::slam::HdbscanMasker inner_;
  bool record_ = false;
  std::mutex mutex_;
  std::map<std::size_t, std::vector<ds3d::ImageBox>> boxes_;
};

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
  DS3D_CHECK_AS(ds3d::IoError, cv::imwrite(path.string(), img), "ds3d-slam: cannot write ",
                path.string());
}

int run(const Args& a) {
  // The source first: a bad --dynamic or --weights fails before any image is read.
  ds3d::slam::DynamicSourceOptions sopt;
  sopt.weights = a.weights;
  sopt.htx.detect_every = a.detect_every;
  if (a.min_score >= 0.0F) sopt.htx.min_score = a.min_score;
  if (a.hold_frames >= 0) sopt.htx.hold_frames = a.hold_frames;
  if (a.segment_frames >= 0) sopt.htx.segment_frames = a.segment_frames;
  sopt.htx.report_floor = a.floor;
  sopt.htx.segment = !a.no_segment;
  sopt.htx.segment_outside_boxes = !a.segment_boxes_only;
  std::shared_ptr<ds3d::slam::DynamicObjectSource> source;
  try {
    source = ds3d::slam::make_dynamic_source(a.dynamic, sopt);
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
  DS3D_CHECK_AS(ds3d::IoError, ds.size() > 0, "ds3d-slam: no associated rgb/depth pairs in ",
                a.dataset.string());
  cv::setNumThreads(a.cv_threads);

  ds3d::slam::FrontendConfig cfg;
  cfg.camera = ds.camera();
  cfg.enable_local_ba = a.local_ba;
  cfg.fuse_neighbors = a.fusion;
  if (a.local_window > 0) cfg.local_window = a.local_window;
  if (a.bf > 0) cfg.bf = a.bf;
  if (a.kf_ratio > 0) cfg.keyframe_ref_ratio = a.kf_ratio;
  if (a.cull_keyframes >= 0) cfg.cull_keyframes = a.cull_keyframes != 0;
  if (a.kf_redundancy > 0) cfg.keyframe_redundancy_ratio = a.kf_redundancy;
  cfg.refine_frame_poses = a.refine;
  if (a.refine_rounds >= 0) cfg.refine_rounds = a.refine_rounds;
  cfg.mapping_thread = a.threads;
  std::shared_ptr<RecordingMasker> masker;
  if (a.dynamic != "none") {
    masker = std::make_shared<RecordingMasker>();
    masker->set_record(!a.viz.empty());
  }
  ds3d::slam::SlamFrontend slam(cfg, source, masker);
  if (!a.viz.empty()) std::filesystem::create_directories(a.viz);

  const std::size_t total = a.max_frames == 0 ? ds.size() : std::min(a.max_frames, ds.size());
  const bool tty = !a.quiet && isatty(fileno(stderr)) != 0;
  std::vector<double> frame_ms;  // wall time between consecutive outputs
  auto last = std::chrono::steady_clock::now();
  const auto t_start = last;
  std::size_t done = 0;
  const auto on_result = [&](const ds3d::slam::TrackResult& r) {
    const auto now = std::chrono::steady_clock::now();
    frame_ms.push_back(std::chrono::duration<double, std::milli>(now - last).count());
    last = now;
    ++done;
    if (!a.viz.empty()) {
      draw_viz(a.viz, ds, r, masker ? masker->take(r.index) : std::vector<ds3d::ImageBox>{});
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
  ds3d::slam::PipelineOptions popt;
  popt.threaded = a.threads;
  const auto results = ds3d::slam::run_dataset(slam, ds, total, on_result, popt);
  if (tty) std::fprintf(stderr, "\n");
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();

  ds3d::write_tum_trajectory(a.out, ds3d::slam::to_trajectory(slam.trajectory()));
  if (!a.keyframes.empty()) {
    ds3d::write_tum_trajectory(a.keyframes, ds3d::slam::to_trajectory(slam.keyframe_trajectory()));
  }
  if (!a.map.empty()) slam.write_map_ply(a.map);

  std::size_t tracked = 0;
  std::size_t lost = 0;
  std::size_t relocalized = 0;
  std::vector<double> ex;
  std::vector<double> de;
  std::vector<double> fi;
  std::vector<double> tr;
  std::vector<double> ex_cpu;
  std::vector<double> tr_cpu;
  for (const auto& r : results) {
    ex_cpu.push_back(r.times.extract_cpu_ms);
    tr_cpu.push_back(r.times.track_cpu_ms);
    tracked += r.tracked ? 1 : 0;
    lost += r.state == ds3d::slam::TrackState::kLost ? 1 : 0;
    relocalized += r.state == ds3d::slam::TrackState::kRelocalized ? 1 : 0;
    ex.push_back(r.times.extract_ms);
    de.push_back(r.times.detect_ms);
    fi.push_back(r.times.filter_ms);
    tr.push_back(r.times.track_ms);
  }
  // The first frames include thread start-up; fps is over the steady state (all intervals but
  // the first) so that it reflects the pipeline's throughput.
  std::vector<double> fps;
  for (std::size_t i = 1; i < frame_ms.size(); ++i)
    fps.push_back(frame_ms[i] > 0 ? 1000.0 / frame_ms[i] : 0.0);
  const auto fps_p = percentiles(fps);
  if (!a.stats.empty()) {
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
       << "  \"dynamic\": \"" << json_escape(a.dynamic) << "\",\n"
       << "  \"detect_every\": " << a.detect_every << ",\n"
       << "  \"frames\": " << results.size() << ",\n"
       << "  \"tracked_frames\": " << tracked << ",\n"
       << "  \"lost_frames\": " << lost << ",\n"
       << "  \"relocalized_frames\": " << relocalized << ",\n"
       << "  \"keyframes\": " << slam.num_keyframes() << ",\n"
       << "  \"culled_keyframes\": " << slam.culled_keyframes().size() << ",\n"
       << "  \"map_points\": " << slam.map_points().rows() << ",\n"
       << "  \"threaded\": " << (a.threads ? "true" : "false") << ",\n"
       << "  \"wall_s\": " << json_number(wall_s) << ",\n"
       << "  \"fps_mean\": " << json_number(static_cast<double>(results.size()) / wall_s) << ",\n"
       << "  \"fps_median\": " << json_number(fps_p.median) << ",\n"
       << "  \"frame_interval\": {\"median_ms\": " << json_number(percentiles(frame_ms).median)
       << ", \"p95_ms\": " << json_number(percentiles(frame_ms).p95) << "},\n"
       << "  \"local_ba\": {\"count\": " << slam.num_local_ba()
       << ", \"total_cpu_ms\": " << json_number(slam.local_ba_ms()) << ", \"mean_cpu_ms\": "
       << json_number(slam.num_local_ba() > 0
                          ? slam.local_ba_ms() / static_cast<double>(slam.num_local_ba())
                          : 0.0)
       << "},\n  \"refine_cpu_ms\": " << json_number(slam.refine_ms()) << ",\n  \"stages\": {\n";
    stage("extract", ex, true);
    stage("detect", de, true);
    stage("filter", fi, true);
    stage("track", tr, false);
    js << "  },\n  \"stages_cpu\": {\n";
    stage("extract", ex_cpu, true);
    stage("track", tr_cpu, false);
    js << "  }\n}\n";
    std::ofstream out(a.stats);
    out << js.str();
    DS3D_CHECK_AS(ds3d::IoError, out.good(), "ds3d-slam: cannot write ", a.stats.string());
  }
  if (!a.quiet) {
    std::cout << "frames " << results.size() << ", tracked " << tracked << ", lost " << lost
              << ", keyframes " << slam.num_keyframes() << ", map points "
              << slam.map_points().rows() << ", " << static_cast<double>(results.size()) / wall_s
              << " fps (median " << fps_p.median << ")\n"
              << "trajectory written to " << a.out.string() << "\n";
  }
  return 0;
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
