// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-slam's safeguards: output paths checked up front, SIGINT/SIGTERM, input warnings.
#include "run_guard.hpp"

#include <unistd.h>

#include <csignal>
#include <iostream>
#include <system_error>

#include "ds3d/dynamic/detections.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"

namespace ds3d_slam_tool {
namespace fs = std::filesystem;

void check_output_paths(const std::vector<OutputPath>& files,
                        const std::vector<OutputPath>& folders) {
  std::error_code ec;
  for (const auto& [flag, path] : files) {
    if (path.empty()) continue;
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    DS3D_CHECK_AS(ds3d::IoError, fs::is_directory(dir, ec), flag, " '", path.string(),
                  "': folder '", dir.string(), "' does not exist");
    DS3D_CHECK_AS(ds3d::IoError, ::access(dir.c_str(), W_OK | X_OK) == 0, flag, " '", path.string(),
                  "': folder '", dir.string(), "' is not writable");
    DS3D_CHECK_AS(ds3d::IoError, !fs::is_directory(path, ec), flag, " '", path.string(),
                  "' is a folder, expected a file name");
  }
  for (const auto& [flag, dir] : folders) {
    if (dir.empty()) continue;
    DS3D_CHECK_AS(ds3d::IoError, !fs::exists(dir, ec) || fs::is_directory(dir, ec), flag, " '",
                  dir.string(), "' exists and is not a folder");
    fs::create_directories(dir, ec);
    DS3D_CHECK_AS(ds3d::IoError, fs::is_directory(dir, ec) && ::access(dir.c_str(), W_OK) == 0,
                  flag, " '", dir.string(), "': cannot create or write the folder");
  }
}

namespace {

volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void on_stop_signal(int sig) {
  g_stop_signal = sig;
  std::signal(sig, SIG_DFL);  // a second signal ends the process at once
}

}  // namespace

void install_stop_handler() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
}

int stop_signal() noexcept { return g_stop_signal; }

std::string signal_name(int sig) {
  if (sig == SIGINT) return "SIGINT";
  if (sig == SIGTERM) return "SIGTERM";
  return "signal " + std::to_string(sig);
}

namespace {

void warn(const std::string& msg) { std::cerr << "ds3d-slam: warning: " << msg << "\n"; }

std::string fixed(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f", v);
  return buf;
}

// The file:PATH parts of an `A+B` source spec.
std::vector<std::string> detection_files(const std::string& spec) {
  std::vector<std::string> out;
  std::size_t pos = 0;
  while (pos <= spec.size()) {
    const std::size_t plus = spec.find('+', pos);
    const std::string part = spec.substr(pos, plus == std::string::npos ? plus : plus - pos);
    if (part.rfind("file:", 0) == 0 && part.size() > 5) out.push_back(part.substr(5));
    if (plus == std::string::npos) break;
    pos = plus + 1;
  }
  return out;
}

std::size_t check_detections(const std::string& path, const ds3d::RgbdDataset& ds,
                             std::size_t begin, std::size_t frames, double max_dt) {
  const auto file = ds3d::DetectionsFile::read(path);
  std::size_t unmatched = 0;
  double first = 0;
  for (std::size_t i = begin; i < begin + frames; ++i) {
    const double t = ds.entries()[i].timestamp;
    if (file.find(t, max_dt) != nullptr) continue;
    if (unmatched++ == 0) first = t;
  }
  if (frames > 0 && unmatched == frames) {
    const auto& f = file.frames();
    throw ds3d::IoError(ds3d::detail::concat(
        "detections file '", path, "' matches none of the ", frames, " frames (frames ",
        fixed(ds.entries()[begin].timestamp), " .. ",
        fixed(ds.entries()[begin + frames - 1].timestamp), " s; file ",
        f.empty() ? std::string("has no lines")
                  : fixed(f.front().timestamp) + " .. " + fixed(f.back().timestamp) + " s",
        "; file.max_dt ", max_dt, " s): wrong file or sequence?"));
  }
  if (unmatched > 0) {
    warn(ds3d::detail::concat("detections file '", path, "' has no line for ", unmatched, " of ",
                              frames, " frames (first at ", fixed(first),
                              " s); those frames get no boxes from it"));
  }
  return unmatched;
}

}  // namespace

InputWarnings check_inputs(const ds3d::RgbdDataset& ds, std::size_t first, std::size_t frames,
                           const ds3d::slam::SlamConfig& config) {
  const auto& d = ds.diagnostics();
  const std::string dir = ds.directory().string();
  if (d.rgb_duplicates > 0) {
    warn(ds3d::detail::concat(dir, "/rgb.txt: ", d.rgb_duplicates,
                              " line(s) dropped for a repeated timestamp (first ",
                              fixed(d.first_rgb_duplicate), "; the later line is kept)"));
  }
  if (d.depth_duplicates > 0) {
    warn(ds3d::detail::concat(dir, "/depth.txt: ", d.depth_duplicates,
                              " line(s) dropped for a repeated timestamp (first ",
                              fixed(d.first_depth_duplicate), "; the later line is kept)"));
  }
  if (d.large_gaps > 0) {
    warn(ds3d::detail::concat(dir, ": ", d.large_gaps, " gap(s) between consecutive frames over ",
                              d.gap_threshold, " s (first: ", d.first_gap_seconds, " s after ",
                              fixed(d.first_gap_start), "); tracking across them may fail"));
  }
  InputWarnings w;
  w.duplicate_rgb_stamps = d.rgb_duplicates;
  w.duplicate_depth_stamps = d.depth_duplicates;
  w.unassociated_rgb = d.unassociated_rgb;
  w.large_gaps = d.large_gaps;
  for (const auto& path : detection_files(config.dynamic)) {
    w.frames_without_detections += check_detections(path, ds, first, frames, config.file.max_dt);
  }
  return w;
}

fs::path htx_weights(const ds3d::slam::SlamConfig& config) {
  const std::string& s = config.dynamic;
  bool htx = false;
  for (std::size_t pos = 0; pos <= s.size();) {
    const std::size_t plus = s.find('+', pos);
    htx = htx || s.substr(pos, plus == std::string::npos ? plus : plus - pos) == "htx";
    if (plus == std::string::npos) break;
    pos = plus + 1;
  }
  if (!htx) return {};
  return config.weights.empty() ? ds3d::slam::find_default_weights() : config.weights;
}

}  // namespace ds3d_slam_tool
