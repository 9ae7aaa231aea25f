// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-slam's safeguards: output paths checked before the first frame, the frames tracked before
// an unreadable frame or a stop signal written out, warnings for suspicious input lists.
#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "ds3d/detail/json.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/slam/synth.hpp"
#include "ds3d/version.hpp"
#include "support/cli.hpp"
#include "support/files.hpp"

extern char** environ;

// GCC 12 -O3 reports a false -Wrestrict inside std::string's operator+ as inlined here.
#pragma GCC diagnostic ignored "-Wrestrict"

namespace {

namespace fs = std::filesystem;

// One 8-frame synthetic sequence per test binary, copied per test.
const fs::path& sequence() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("ds3d_slam_cli_" + std::to_string(::getpid()));
    fs::remove_all(d);
    ds3d::synth::SynthOptions o;
    o.scenario = ds3d::synth::Scenario::kStaticRoom;
    o.num_frames = 8;
    o.seed = 3;
    (void)ds3d::synth::generate_sequence(d / "seq", o);
    return d / "seq";
  }();
  return dir;
}

// Whether process `pid` still has a handler for SIGINT (SigCgt of /proc/PID/status).
bool sigint_caught(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("SigCgt:", 0) == 0) {
      return (std::stoull(line.substr(7), nullptr, 16) & (1ULL << (SIGINT - 1))) != 0;
    }
  }
  return false;
}

class Ds3dSlamCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(ds3d::test::tool_path("ds3d-slam"))) GTEST_SKIP() << "ds3d-slam not built";
    work_ =
        sequence().parent_path() / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(work_);
    fs::create_directories(work_);
    fs::copy(sequence(), work_ / "seq", fs::copy_options::recursive);
  }
  void TearDown() override {
    if (!work_.empty()) fs::remove_all(work_);
  }
  // The rgb or depth file of frame i (as listed).
  [[nodiscard]] fs::path listed(const char* list, std::size_t i) const {
    const auto lines = ds3d::test::read_lines(work_ / "seq" / list);
    std::size_t k = 0;
    for (const auto& l : lines) {
      if (l.empty() || l[0] == '#') continue;
      if (k++ == i) return work_ / "seq" / l.substr(l.find(' ') + 1);
    }
    return {};
  }
  [[nodiscard]] std::string args(const std::string& extra = "") const {
    return "'" + (work_ / "seq").string() + "' --quiet --out '" + (work_ / "traj.txt").string() +
           "' --stats '" + (work_ / "stats.json").string() + "' " + extra;
  }
  [[nodiscard]] std::size_t poses() const {
    return ds3d::read_tum_trajectory(work_ / "traj.txt").size();
  }
  fs::path work_;
};

TEST_F(Ds3dSlamCli, OutputPathsAreCheckedBeforeTheFirstFrame) {
  const fs::path missing = work_ / "no" / "such";
  auto r = ds3d::test::run_tool("ds3d-slam", "'" + (work_ / "seq").string() + "' --out '" +
                                                 (missing / "t.txt").string() + "'");
  EXPECT_NE(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("--out '" + (missing / "t.txt").string() + "': folder '" +
                          missing.string() + "' does not exist"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("frames "), std::string::npos) << "frames were run:\n" << r.output;
  for (const char* flag : {"--stats", "--keyframes", "--map"}) {
    r = ds3d::test::run_tool("ds3d-slam",
                             args(std::string(flag) + " '" + (missing / "x").string() + "'"));
    EXPECT_NE(r.code, 0) << flag;
    EXPECT_NE(r.output.find(std::string(flag) + " '"), std::string::npos) << r.output;
  }
  std::ofstream(work_ / "afile") << "x";
  r = ds3d::test::run_tool("ds3d-slam", args("--viz '" + (work_ / "afile").string() + "'"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("is not a folder"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(work_ / "traj.txt"));
}

// Frame 5 of 8 unreadable in several ways: exit 1 naming the file, and the 5 frames before it
// tracked and written, with stopped_early in --stats.
TEST_F(Ds3dSlamCli, FrameErrorKeepsTheFramesTrackedSoFar) {
  const fs::path rgb5 = listed("rgb.txt", 5);
  const fs::path depth5 = listed("depth.txt", 5);
  const std::string png = ds3d::test::read_file(rgb5);
  const std::string depth_png = ds3d::test::read_file(depth5);
  struct Case {
    const char* name;
    std::function<void()> damage;
    std::string needle;
  };
  const std::vector<Case> cases = {
      {"truncated PNG", [&] { std::ofstream(rgb5, std::ios::binary) << png.substr(0, 200); },
       rgb5.string()},
      {"missing file", [&] { fs::remove(rgb5); }, rgb5.string()},
      {"8-bit depth",
       [&] { cv::imwrite(depth5.string(), cv::Mat(480, 640, CV_8UC1, cv::Scalar(9))); },
       "must be 16-bit"},
      {"size mismatch",
       [&] { cv::imwrite(depth5.string(), cv::Mat(240, 320, CV_16UC1, cv::Scalar(900))); },
       "320x240"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    std::ofstream(rgb5, std::ios::binary) << png;
    std::ofstream(depth5, std::ios::binary) << depth_png;
    fs::remove(work_ / "traj.txt");
    c.damage();
    const auto r = ds3d::test::run_tool("ds3d-slam", args());
    EXPECT_EQ(r.code, 1) << r.output;
    EXPECT_NE(r.output.find(c.needle), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("stopped early (frame error) after 5 of 8 frames"), std::string::npos)
        << r.output;
    ASSERT_TRUE(fs::exists(work_ / "traj.txt")) << r.output;
    EXPECT_EQ(poses(), 5U);
    const auto stats = ds3d::test::read_json(work_ / "stats.json");
    EXPECT_TRUE(stats.at("stopped_early").as_bool());
    EXPECT_EQ(stats.at("stop_reason").as_string(), "frame error");
    EXPECT_EQ(stats.at("frames").as_number(), 5.0);
    EXPECT_EQ(stats.at("frames_requested").as_number(), 8.0);
  }
  // No temporary file is left beside the outputs.
  for (const auto& e : fs::directory_iterator(work_)) {
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  }
}

// SIGINT while frame 3 is being read (its rgb file is a FIFO the test holds open: no timing):
// the frames read before it are tracked and written, exit 130.
TEST_F(Ds3dSlamCli, SigintWritesTheFramesTrackedSoFar) {
  const fs::path rgb3 = listed("rgb.txt", 3);
  fs::remove(rgb3);
  ASSERT_EQ(::mkfifo(rgb3.c_str(), 0600), 0);
  const std::string cmd = "exec '" + ds3d::test::tool_path("ds3d-slam").string() + "' " + args() +
                          " > '" + (work_ / "log.txt").string() + "' 2>&1";
  const char* argv[] = {"sh", "-c", cmd.c_str(), nullptr};
  pid_t pid = 0;
  ASSERT_EQ(::posix_spawn(&pid, "/bin/sh", nullptr, nullptr, const_cast<char**>(argv), environ), 0);
  // Opening the FIFO for writing blocks until ds3d-slam opens it to read frame 3.
  int fd = ::open(rgb3.c_str(), O_WRONLY);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::kill(pid, SIGINT), 0);
  // The handler has run once SIGINT is no longer in the caught set (it restores the default).
  while (sigint_caught(pid)) ::usleep(1000);
  ::close(fd);  // EOF: the frame is unreadable, but the stop request came first
  // Every later reader of the FIFO (the image decoder) gets EOF as well, until ds3d-slam exits.
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    fd = ::open(rgb3.c_str(), O_WRONLY | O_NONBLOCK);
    if (fd >= 0) ::close(fd);
    ::usleep(1000);
  }
  const std::string log = ds3d::test::read_file(work_ / "log.txt");
  ASSERT_TRUE(WIFEXITED(status)) << log;
  EXPECT_EQ(WEXITSTATUS(status), 130) << log;
  EXPECT_NE(log.find("stopped early (SIGINT) after 3 of 8 frames"), std::string::npos) << log;
  EXPECT_EQ(poses(), 3U);
  const auto stats = ds3d::test::read_json(work_ / "stats.json");
  EXPECT_TRUE(stats.at("stopped_early").as_bool());
  EXPECT_EQ(stats.at("stop_reason").as_string(), "SIGINT");
}

TEST_F(Ds3dSlamCli, WarnsAboutDuplicateStampsGapsAndUnmatchedDetections) {
  // rgb.txt: frame 2's line repeated (one line dropped), and frames 4.. shifted by 1000 s.
  std::vector<std::string> rgb;
  std::vector<std::string> depth;
  for (const char* list : {"rgb.txt", "depth.txt"}) {
    auto& out = list[0] == 'r' ? rgb : depth;
    std::size_t k = 0;
    for (const auto& l : ds3d::test::read_lines(work_ / "seq" / list)) {
      if (l.empty() || l[0] == '#') continue;
      const double t = std::stod(l.substr(0, l.find(' '))) + (k++ >= 4 ? 1000.0 : 0.0);
      out.push_back(std::to_string(t) + l.substr(l.find(' ')));
    }
  }
  rgb.insert(rgb.begin() + 2, rgb[2].substr(0, rgb[2].find(' ')) + " " +
                                  listed("rgb.txt", 1).lexically_relative(work_ / "seq").string());
  for (const auto& [name, lines] : {std::pair{"rgb.txt", rgb}, std::pair{"depth.txt", depth}}) {
    std::ofstream out(work_ / "seq" / name);
    for (const auto& l : lines) out << l << "\n";
  }
  // Detections for the first two frames only.
  {
    std::ofstream det(work_ / "det.jsonl");
    for (std::size_t i = 0; i < 2; ++i) {
      det << "{\"timestamp\": " << rgb[i].substr(0, rgb[i].find(' ')) << ", \"detections\": []}\n";
    }
  }
  auto r = ds3d::test::run_tool("ds3d-slam",
                                args("--dynamic 'file:" + (work_ / "det.jsonl").string() + "'"));
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("rgb.txt: 1 line(s) dropped for a repeated timestamp"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("1 gap(s) between consecutive frames"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("has no line for 6 of 8 frames"), std::string::npos) << r.output;
  const auto stats = ds3d::test::read_json(work_ / "stats.json");
  const auto& w = stats.at("input_warnings");
  EXPECT_EQ(w.at("duplicate_rgb_stamps").as_number(), 1.0);
  EXPECT_EQ(w.at("large_gaps").as_number(), 1.0);
  EXPECT_EQ(w.at("frames_without_detections").as_number(), 6.0);
  EXPECT_FALSE(stats.at("stopped_early").as_bool());
  // finish()'s counters are reported.
  EXPECT_GE(stats.at("merged_segments").as_number(), 0.0);
  EXPECT_GE(stats.at("interpolated_frames").as_number(), 0.0);
  // Frame-in to pose-out latency, and the source's stages (wall and thread CPU).
  const auto& latency = stats.at("latency");
  EXPECT_GT(latency.at("median_ms").as_number(), 0.0);
  EXPECT_GE(latency.at("p95_ms").as_number(), latency.at("median_ms").as_number());
  for (const char* group : {"stages", "stages_cpu"}) {
    EXPECT_GE(stats.at(group).at("detect").at("median_ms").as_number(), 0.0) << group;
    EXPECT_GE(stats.at(group).at("prepare").at("median_ms").as_number(), 0.0) << group;
  }
  // Per-frame times: one finite, non-negative entry per frame.
  const auto& per_frame = stats.at("per_frame");
  for (const char* key :
       {"interval_ms", "latency_ms", "extract_ms", "detect_ms", "track_ms", "track_cpu_ms"}) {
    const auto& a = per_frame.at(key).as_array();
    ASSERT_EQ(a.size(), per_frame.at("state").as_array().size()) << key;
    for (const auto& v : a) {
      EXPECT_TRUE(std::isfinite(v.as_number()) && v.as_number() >= 0.0) << key;
    }
  }
  // A detections file that matches no frame at all is an error naming it.
  std::ofstream(work_ / "other.jsonl") << "{\"timestamp\": 5.0, \"detections\": []}\n";
  r = ds3d::test::run_tool("ds3d-slam",
                           args("--dynamic 'file:" + (work_ / "other.jsonl").string() + "'"));
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("detections file '" + (work_ / "other.jsonl").string() +
                          "' matches none of the 8 frames"),
            std::string::npos)
      << r.output;
}

// A 32-frame synthetic sequence for the options that pick frames, generated once.
const fs::path& long_sequence() {
  static const fs::path dir = [] {
    const fs::path d = sequence().parent_path() / "long";
    ds3d::synth::SynthOptions o;
    o.scenario = ds3d::synth::Scenario::kStaticRoom;
    o.num_frames = 32;
    o.seed = 5;
    o.camera = ds3d::PinholeCamera{.fx = 262.5,
                                   .fy = 262.5,
                                   .cx = 159.5,
                                   .cy = 119.5,
                                   .width = 320,
                                   .height = 240};  // fast to render and track
    (void)ds3d::synth::generate_sequence(d, o);
    return d;
  }();
  return dir;
}

// The associated frame stamps of a sequence, in order.
std::vector<double> frame_stamps(const fs::path& seq) {
  std::vector<double> out;
  const auto ds = ds3d::RgbdDataset::open(seq);
  for (const auto& e : ds.entries()) out.push_back(e.timestamp);
  return out;
}

// --start-frame 10 --max-frames 20: the 20 poses of frames 10 .. 29; bad values name the option.
TEST_F(Ds3dSlamCli, StartFrameSkipsTheFirstFrames) {
  const fs::path seq = long_sequence();
  const auto stamps = frame_stamps(seq);
  ASSERT_EQ(stamps.size(), 32U);
  const std::string out = " --quiet --out '" + (work_ / "traj.txt").string() + "' --stats '" +
                          (work_ / "stats.json").string() + "'";
  auto r = ds3d::test::run_tool(
      "ds3d-slam", "'" + seq.string() + "'" + out + " --start-frame 10 --max-frames 20");
  ASSERT_EQ(r.code, 0) << r.output;
  auto traj = ds3d::read_tum_trajectory(work_ / "traj.txt");
  ASSERT_EQ(traj.size(), 20U);
  for (std::size_t i = 0; i < traj.size(); ++i) EXPECT_EQ(traj[i].timestamp, stamps[10 + i]) << i;
  EXPECT_EQ(ds3d::test::read_json(work_ / "stats.json").at("frames").as_number(), 20.0);
  // Without --max-frames: to the end.
  r = ds3d::test::run_tool("ds3d-slam", "'" + seq.string() + "'" + out + " --start-frame 29");
  ASSERT_EQ(r.code, 0) << r.output;
  traj = ds3d::read_tum_trajectory(work_ / "traj.txt");
  ASSERT_EQ(traj.size(), 3U);
  EXPECT_EQ(traj.front().timestamp, stamps[29]);
  EXPECT_EQ(traj.back().timestamp, stamps[31]);
  for (const std::string bad : {"32", "-1", "x", ""}) {
    SCOPED_TRACE(bad);
    fs::remove(work_ / "traj.txt");
    r = ds3d::test::run_tool("ds3d-slam",
                             "'" + seq.string() + "'" + out + " --start-frame '" + bad + "'");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_EQ(r.output.rfind("ds3d-slam: --start-frame ", 0), 0U) << r.output;
    EXPECT_FALSE(fs::exists(work_ / "traj.txt"));
    if (bad == "32") {
      EXPECT_NE(r.output.find("has 32 associated frames"), std::string::npos) << r.output;
    }
  }
}

// --realtime hands the frames over at the rate of their timestamps: the run lasts at least the
// recording's span, and the trajectory is the one of a run that reads as fast as it can.
TEST_F(Ds3dSlamCli, RealtimePlaysAtTheRecordedRateWithTheSameTrajectory) {
  const auto stamps = frame_stamps(work_ / "seq");
  ASSERT_EQ(stamps.size(), 8U);
  auto r = ds3d::test::run_tool("ds3d-slam", args());
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string fast = ds3d::test::read_file(work_ / "traj.txt");
  auto stats = ds3d::test::read_json(work_ / "stats.json");
  EXPECT_FALSE(stats.at("realtime").as_bool());
  EXPECT_TRUE(stats.at("input_lag").is_null());

  const auto t0 = std::chrono::steady_clock::now();
  r = ds3d::test::run_tool("ds3d-slam", args("--realtime"));
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(ds3d::test::read_file(work_ / "traj.txt"), fast);
  const double span = stamps.back() - stamps.front();
  EXPECT_GE(wall, span);
  stats = ds3d::test::read_json(work_ / "stats.json");
  EXPECT_TRUE(stats.at("realtime").as_bool());
  EXPECT_GE(stats.at("wall_s").as_number(), span);
  const auto& lag = stats.at("input_lag");
  EXPECT_GE(lag.at("median_ms").as_number(), 0.0);
  EXPECT_GE(lag.at("p95_ms").as_number(), lag.at("median_ms").as_number());
  EXPECT_GE(lag.at("max_ms").as_number(), lag.at("p95_ms").as_number());
  // Latency counts from when a live camera would have delivered each frame.
  const auto& latency = stats.at("per_frame").at("latency_ms").as_array();
  ASSERT_EQ(latency.size(), 8U);
  for (const auto& v : latency) EXPECT_TRUE(std::isfinite(v.as_number()) && v.as_number() > 0.0);
}

// SIGINT while --realtime waits out a 1000-s gap in the recording: the run stops at once and
// writes the frames tracked so far.
TEST_F(Ds3dSlamCli, RealtimeStopsDuringAGapOnSigint) {
  for (const char* list : {"rgb.txt", "depth.txt"}) {
    std::vector<std::string> lines;
    std::size_t k = 0;
    for (const auto& l : ds3d::test::read_lines(work_ / "seq" / list)) {
      if (l.empty() || l[0] == '#') continue;
      const double t = std::stod(l.substr(0, l.find(' '))) + (k++ >= 4 ? 1000.0 : 0.0);
      lines.push_back(std::to_string(t) + l.substr(l.find(' ')));
    }
    std::ofstream out(work_ / "seq" / list);
    for (const auto& l : lines) out << l << "\n";
  }
  const std::string cmd = "exec '" + ds3d::test::tool_path("ds3d-slam").string() + "' " +
                          args("--realtime") + " > '" + (work_ / "log.txt").string() + "' 2>&1";
  const char* argv[] = {"sh", "-c", cmd.c_str(), nullptr};
  pid_t pid = 0;
  ASSERT_EQ(::posix_spawn(&pid, "/bin/sh", nullptr, nullptr, const_cast<char**>(argv), environ), 0);
  while (!sigint_caught(pid)) ::usleep(1000);  // the stop handler is installed
  ::usleep(2000 * 1000);  // frames 0-3 take 0.1 s of recording: the reader now waits for frame 4
  ASSERT_EQ(::kill(pid, SIGINT), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  const std::string log = ds3d::test::read_file(work_ / "log.txt");
  ASSERT_TRUE(WIFEXITED(status)) << log;
  EXPECT_EQ(WEXITSTATUS(status), 130) << log;
  EXPECT_LE(poses(), 4U);
  const auto stats = ds3d::test::read_json(work_ / "stats.json");
  EXPECT_TRUE(stats.at("stopped_early").as_bool());
  EXPECT_LT(stats.at("wall_s").as_number(), 60.0);  // not the 1000 s of the gap
}

// A 6-frame sequence with two walkers, their ground-truth masks (mask/) and detections with
// 3-D boxes (detections_noisy.jsonl, a miss rate small enough to keep every box here).
const fs::path& walking_sequence() {
  static const fs::path dir = [] {
    const fs::path d = sequence().parent_path() / "walking";
    ds3d::synth::SynthOptions o;
    o.scenario = ds3d::synth::Scenario::kWalkingXyz;
    o.num_frames = 6;
    o.seed = 2;
    o.detection_miss = 1e-6;
    (void)ds3d::synth::generate_sequence(d, o);
    return d;
  }();
  return dir;
}

// --dynamic-out DIR: one mask PNG (image-sized, 0/255) and one keypoints.jsonl line per frame.
struct DynamicOut {
  std::vector<cv::Mat> masks;
  std::vector<ds3d::detail::JsonValue> lines;
};
DynamicOut read_dynamic_out(const fs::path& dir, const std::vector<double>& stamps) {
  DynamicOut out;
  for (const auto& l : ds3d::test::read_lines(dir / "keypoints.jsonl")) {
    out.lines.push_back(ds3d::detail::parse_json(l));
  }
  for (std::size_t i = 0; i < out.lines.size(); ++i) {
    const auto& j = out.lines[i];
    EXPECT_EQ(j.at("timestamp").as_number(), stamps[i]);
    EXPECT_EQ(j.at("frame").as_number(), static_cast<double>(i));
    EXPECT_EQ(j.at("u").size(), j.at("status").size());
    EXPECT_EQ(j.at("v").size(), j.at("status").size());
    out.masks.push_back(
        cv::imread((dir / j.at("mask").as_string()).string(), cv::IMREAD_UNCHANGED));
  }
  return out;
}

// The keypoints of one line with a given status, as rounded pixels.
std::vector<cv::Point> keypoints_with(const ds3d::detail::JsonValue& line, const char* status) {
  std::vector<cv::Point> out;
  for (std::size_t k = 0; k < line.at("status").size(); ++k) {
    if (line.at("status").at(k).as_string() != status) continue;
    out.emplace_back(static_cast<int>(std::lround(line.at("u").at(k).as_number())),
                     static_cast<int>(std::lround(line.at("v").at(k).as_number())));
  }
  return out;
}

// mask:DIR source: the PNG is the source's mask, and the dynamic keypoints lie on it. file:PATH
// source (3-D boxes): the PNG holds the boxes, and every dynamic keypoint lies in one.
TEST_F(Ds3dSlamCli, DynamicOutWritesMasksAndKeypointLabels) {
  const fs::path seq = walking_sequence();
  const auto stamps = frame_stamps(seq);
  const fs::path dir = work_ / "dyn" / "out";  // created with its parent
  auto r = ds3d::test::run_tool("ds3d-slam", "'" + seq.string() + "' --quiet --out '" +
                                                 (work_ / "traj.txt").string() +
                                                 "' --dynamic 'mask:" + (seq / "mask").string() +
                                                 "' --dynamic-out '" + dir.string() + "'");
  ASSERT_EQ(r.code, 0) << r.output;
  auto out = read_dynamic_out(dir, stamps);
  ASSERT_EQ(out.lines.size(), 6U);
  std::size_t dynamic_keypoints = 0;
  for (std::size_t i = 0; i < out.lines.size(); ++i) {
    SCOPED_TRACE(i);
    char name[64];
    std::snprintf(name, sizeof(name), "%.6f.png", stamps[i]);
    ASSERT_TRUE(fs::exists(dir / name));
    const cv::Mat& m = out.masks[i];
    ASSERT_EQ(m.type(), CV_8UC1);
    ASSERT_EQ(m.size(), cv::Size(640, 480));
    const cv::Mat gt = cv::imread((seq / "mask" / name).string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(cv::countNonZero(m != (gt != 0)), 0) << "differs from the source's mask";
    EXPECT_EQ(cv::countNonZero(m != 0) + cv::countNonZero(m == 0), 640 * 480);
    EXPECT_GT(cv::countNonZero(m), 0) << "no walker in frame " << i;
    const auto dyn = keypoints_with(out.lines[i], "dynamic");
    for (const auto& p : dyn) EXPECT_EQ(m.at<std::uint8_t>(p), 255) << p;
    dynamic_keypoints += dyn.size();
    EXPECT_FALSE(keypoints_with(out.lines[i], "tracked").empty());
  }
  EXPECT_GT(dynamic_keypoints, 20U);
  // The same trajectory as without --dynamic-out.
  const std::string with = ds3d::test::read_file(work_ / "traj.txt");
  r = ds3d::test::run_tool("ds3d-slam", "'" + seq.string() + "' --quiet --out '" +
                                            (work_ / "traj.txt").string() +
                                            "' --dynamic 'mask:" + (seq / "mask").string() + "'");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(ds3d::test::read_file(work_ / "traj.txt"), with);

  const fs::path det = seq / "detections_noisy.jsonl";
  ASSERT_TRUE(fs::exists(det));
  r = ds3d::test::run_tool("ds3d-slam", "'" + seq.string() + "' --quiet --out '" +
                                            (work_ / "traj.txt").string() +
                                            "' --dynamic 'file:" + det.string() +
                                            "' --dynamic-out '" + dir.string() + "'");
  ASSERT_EQ(r.code, 0) << r.output;
  out = read_dynamic_out(dir, stamps);
  ASSERT_EQ(out.lines.size(), 6U);
  dynamic_keypoints = 0;
  for (std::size_t i = 0; i < out.lines.size(); ++i) {
    const cv::Mat& m = out.masks[i];
    ASSERT_EQ(m.size(), cv::Size(640, 480));
    EXPECT_GT(cv::countNonZero(m), 0) << i;
    for (const auto& p : keypoints_with(out.lines[i], "dynamic")) {
      EXPECT_EQ(m.at<std::uint8_t>(p), 255) << i << " " << p;
      ++dynamic_keypoints;
    }
  }
  EXPECT_GT(dynamic_keypoints, 20U);
}

// The folder is checked before the first frame, and a run stopped by an unreadable frame leaves
// the files of the frames done; without a dynamic source the masks are empty.
TEST_F(Ds3dSlamCli, DynamicOutIsCheckedFirstAndKeptOnEarlyStop) {
  std::ofstream(work_ / "afile") << "x";
  auto r =
      ds3d::test::run_tool("ds3d-slam", args("--dynamic-out '" + (work_ / "afile").string() + "'"));
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("--dynamic-out '" + (work_ / "afile").string() +
                          "' exists and is not a folder"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(work_ / "traj.txt"));
  fs::remove(listed("rgb.txt", 3));
  const fs::path dir = work_ / "dyn";
  r = ds3d::test::run_tool("ds3d-slam", args("--dynamic-out '" + dir.string() + "'"));
  EXPECT_EQ(r.code, 1) << r.output;
  const auto out = read_dynamic_out(dir, frame_stamps(work_ / "seq"));
  ASSERT_EQ(out.lines.size(), 3U);
  std::size_t pngs = 0;
  for (const auto& e : fs::directory_iterator(dir)) pngs += e.path().extension() == ".png" ? 1 : 0;
  EXPECT_EQ(pngs, 3U);
  for (const auto& m : out.masks) {
    ASSERT_EQ(m.size(), cv::Size(640, 480));
    EXPECT_EQ(cv::countNonZero(m), 0);
  }
  EXPECT_TRUE(keypoints_with(out.lines[2], "dynamic").empty());
}

// Every tool answers --version (its name and the library version, exit 0) and --help (its
// usage on stdout, exit 0).
TEST(Tools, EveryToolAnswersVersionAndHelp) {
  for (const std::string tool : {"ds3d-slam", "ds3d-eval", "ds3d-synth", "ds3d-demo"}) {
    if (!fs::exists(ds3d::test::tool_path(tool))) continue;
    auto r = ds3d::test::run_tool(tool, "--version");
    EXPECT_EQ(r.code, 0) << tool << ": " << r.output;
    EXPECT_EQ(r.output, tool + " " + ds3d::kVersion + "\n");
    r = ds3d::test::run_tool(tool, "--help");
    EXPECT_EQ(r.code, 0) << tool << ": " << r.output;
    EXPECT_NE(r.output.find("usage: " + tool), std::string::npos) << tool << ": " << r.output;
  }
}

// ds3d-slam's --help says which --dynamic to use when, with the default first.
TEST(Tools, SlamHelpSaysWhichDynamicModeToUse) {
  if (!fs::exists(ds3d::test::tool_path("ds3d-slam"))) GTEST_SKIP() << "ds3d-slam not built";
  const auto r = ds3d::test::run_tool("ds3d-slam", "--help");
  ASSERT_EQ(r.code, 0) << r.output;
  const auto table = r.output.find("Which --dynamic to use");
  ASSERT_NE(table, std::string::npos) << r.output;
  EXPECT_NE(r.output.find("geometric (default)", table), std::string::npos) << r.output;
  for (const std::string mode :
       {"none", "htx+geometric", "htx --gate motion", "file:PATH+geometric"})
    EXPECT_NE(r.output.find("  " + mode + " ", table), std::string::npos) << mode;
}

}  // namespace
