// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-eval: ATE and RPE of estimates against ground truth, with the numbers of the TUM
// benchmark scripts (evaluate_ate.py / evaluate_rpe.py --verbose) or JSON; trajectories in TUM,
// KITTI or EuRoC format (trajectory_formats.hpp), and `convert` between them.
// ate --window W adds the local ATE: the pairs cut into W-second windows, each aligned alone.
// Usage: see kUsage.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <iostream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "ds3d/detail/json.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_formats.hpp"
#include "ds3d/eval/trajectory_frames.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "ds3d/slam/trajectory_plot.hpp"
#include "ds3d/version.hpp"

// GCC 12 -O3 reports a false -Wrestrict inside std::string's operator+ as inlined here.
#pragma GCC diagnostic ignored "-Wrestrict"

namespace {

using ds3d::detail::json_number;

constexpr const char* kUsage =
    "usage: ds3d-eval ate GT EST [EST2 ...] [--max-difference 0.02] [--offset 0] [--scale 1]\n"
    "                 [--align se3|sim3|none] [--window SECONDS] [--plot out.png]\n"
    "                 [--json] [FORMAT OPTIONS]\n"
    "       ds3d-eval rpe GT EST [EST2 ...] [--delta 1] [--delta-unit s|f|m|rad|deg]\n"
    "                 [--offset 0] [--scale 1] [--all-pairs] [--max-pairs 10000] [--evo]\n"
    "                 [--seed 1] [--json] [FORMAT OPTIONS]\n"
    "       ds3d-eval convert IN OUT [--to tum|kitti|euroc] [--bonn-camera] [FORMAT OPTIONS]\n"
    "       ds3d-eval --help | --version\n"
    "Several estimates are evaluated one after the other against GT (text: a line 'estimate\n"
    "FILE' before each block; --json: {\"ground_truth\", \"estimates\": [...]}); --plot then\n"
    "draws them all in one image with an error colour bar.\n"
    "FORMAT OPTIONS: --format tum|kitti|euroc (every file read), --gt-format F, --est-format F,\n"
    "  --timestamps FILE (one stamp per line, e.g. KITTI's times.txt: the stamps of KITTI\n"
    "  files, else their line index 0, 1, 2, ... in seconds). Without them the format is\n"
    "  detected: .csv is EuRoC, 12 numbers a line KITTI, else TUM. convert writes --to, else\n"
    "  EuRoC for OUT ending in .csv, else TUM (KITTI output has no timestamps).\n"
    "--bonn-camera (convert): IN is a Bonn RGB-D Dynamic groundtruth.txt (motion-capture marker\n"
    "  poses); OUT gets the camera poses by the dataset's fixed transforms (docs/eval.md).\n";

int usage(const std::string& msg) {
  std::cerr << "ds3d-eval: " << msg << "\n" << kUsage;
  return 2;
}

double to_double(const std::string& flag, const std::string& v) {
  const auto d = ds3d::detail::parse_py_float(v);
  if (!d) throw ds3d::InvalidArgument(flag + " expects a number (got '" + v + "')");
  return *d;
}

/// A non-negative integer option up to `max` (exactly representable), else InvalidArgument.
std::uint64_t to_count(const std::string& flag, const std::string& v, double max) {
  const double d = to_double(flag, v);
  if (!(d >= 0 && d <= max && d == std::floor(d))) {
    throw ds3d::InvalidArgument(flag + " must be an integer in [0, " + json_number(max) +
                                "] (got '" + v + "')");
  }
  return static_cast<std::uint64_t>(d);
}

std::string stats_json(const ds3d::ErrorStats& s, const char* unit) {
  return std::string("{\"unit\":\"") + unit + "\",\"rmse\":" + json_number(s.rmse) +
         ",\"mean\":" + json_number(s.mean) + ",\"median\":" + json_number(s.median) +
         ",\"std\":" + json_number(s.std) + ",\"min\":" + json_number(s.min) +
         ",\"max\":" + json_number(s.max) + "}";
}

void print_line(const char* name, double v, const char* unit) {
  std::printf("%s %f %s\n", name, v, unit);
}

/// The six lines `<prefix>.rmse` ... `<prefix>.max` as the TUM scripts print them (--verbose).
void print_stats(const std::string& prefix, const ds3d::ErrorStats& s, const char* unit) {
  const std::pair<const char*, double> rows[] = {{"rmse", s.rmse},     {"mean", s.mean},
                                                 {"median", s.median}, {"std", s.std},
                                                 {"min", s.min},       {"max", s.max}};
  for (const auto& [name, value] : rows) print_line((prefix + "." + name).c_str(), value, unit);
}

/// `,"windows":[...],"worst_window_rmse":X,"num_short_windows":K` for the ATE object.
std::string windows_json(const ds3d::AteResult& r) {
  std::string out = ",\"windows\":[";
  for (std::size_t k = 0; k < r.windows.size(); ++k) {
    const auto& w = r.windows[k];
    out += std::string(k ? "," : "") + "{\"start\":" + json_number(w.start) +
           ",\"end\":" + json_number(w.end) + ",\"pairs\":" + std::to_string(w.pairs) +
           ",\"rmse\":" + json_number(w.rmse) + "}";
  }
  return out + "],\"worst_window_rmse\":" + json_number(r.worst_window_rmse) +
         ",\"num_short_windows\":" + std::to_string(r.num_short_windows);
}

/// The two local-ATE lines after the TUM ones.
void print_windows(const ds3d::AteResult& r, double window) {
  std::printf("windows %zu (%g s each", r.windows.size(), window);
  if (r.num_short_windows > 0) std::printf(", %zu skipped with < 3 pairs", r.num_short_windows);
  std::printf(")\n");
  const auto worst = std::max_element(
      r.windows.begin(), r.windows.end(),
      [](const ds3d::AteWindow& a, const ds3d::AteWindow& b) { return a.rmse < b.rmse; });
  if (worst == r.windows.end()) {
    std::printf("worst_window_rmse %f m (no window with >= 3 pairs)\n", r.worst_window_rmse);
  } else {
    std::printf("worst_window_rmse %f m (start %f end %f)\n", worst->rmse, worst->start,
                worst->end);
  }
}

/// Runs `evaluate` and appends both file names to an InvalidArgument (bad data in one of them).
template <class F>
auto with_files(const std::string& gt_path, const std::string& est_path, const F& evaluate) {
  try {
    return evaluate();
  } catch (const ds3d::InvalidArgument& e) {
    throw ds3d::InvalidArgument(std::string(e.what()) + " (ground truth '" + gt_path +
                                "', estimate '" + est_path + "')");
  }
}

/// The one line of an error; the tool's name is added here only, never in the messages.
std::string error_line(const std::string& what) { return "ds3d-eval: error: " + what; }

/// A command-line mistake: printed with the usage, exit code 2.
struct UsageError {
  std::string message;
};

/// The parsed command line.
struct Args {
  std::string cmd;                 // ate, rpe or convert
  std::vector<std::string> files;  // ate/rpe: GT, then the estimates; convert: IN, OUT
  ds3d::AteOptions ate;
  ds3d::RpeOptions rpe;
  std::string plot;
  bool json = false;
  std::optional<ds3d::TrajectoryFormat> gt_format;
  std::optional<ds3d::TrajectoryFormat> est_format;  // and convert's IN
  std::optional<ds3d::TrajectoryFormat> to;
  std::string timestamps;
  bool bonn_camera = false;  // convert: marker poses of the Bonn dataset -> camera poses
};

/// An option of ate and rpe (false when `a` is none of them).
bool metric_option(Args& r, const std::string& a, const std::function<std::string()>& value) {
  const std::string& cmd = r.cmd;
  if (a == "--json") {
    r.json = true;
  } else if (a == "--offset") {
    r.ate.offset = r.rpe.offset = to_double(a, value());
  } else if (a == "--scale") {
    r.ate.scale = r.rpe.scale = to_double(a, value());
  } else if (cmd == "ate" && a == "--max-difference") {
    r.ate.max_difference = to_double(a, value());
  } else if (cmd == "ate" && a == "--align") {
    r.ate.alignment = ds3d::parse_alignment(value());
  } else if (cmd == "ate" && a == "--window") {
    r.ate.window = to_double(a, value());
  } else if (cmd == "ate" && a == "--plot") {
    r.plot = value();
  } else if (cmd == "rpe" && a == "--delta") {
    r.rpe.delta = to_double(a, value());
  } else if (cmd == "rpe" && a == "--delta-unit") {
    r.rpe.delta_unit = ds3d::parse_delta_unit(value());
  } else if (cmd == "rpe" && a == "--all-pairs") {
    r.rpe.fixed_delta = false;
  } else if (cmd == "rpe" && a == "--max-pairs") {
    r.rpe.max_pairs = static_cast<std::size_t>(to_count(a, value(), 1e12));
  } else if (cmd == "rpe" && a == "--evo") {
    r.rpe.convention = ds3d::RpeConvention::kEvo;
  } else if (cmd == "rpe" && a == "--seed") {
    r.rpe.seed = to_count(a, value(), 0x1p53);
  } else {
    return false;
  }
  return true;
}

/// "--gt-format F: ..." for a bad format name.
ds3d::TrajectoryFormat format_value(const std::string& flag, const std::string& v) {
  try {
    return ds3d::parse_trajectory_format(v);
  } catch (const ds3d::InvalidArgument&) {
    throw ds3d::InvalidArgument(flag + " must be tum, kitti or euroc (got '" + v + "')");
  }
}

/// A format option (false when `a` is none of them).
bool format_option(Args& r, const std::string& a, const std::function<std::string()>& value) {
  if (a == "--format") {
    r.gt_format = r.est_format = format_value(a, value());
  } else if (r.cmd != "convert" && a == "--gt-format") {
    r.gt_format = format_value(a, value());
  } else if (r.cmd != "convert" && a == "--est-format") {
    r.est_format = format_value(a, value());
  } else if (r.cmd == "convert" && a == "--to") {
    r.to = format_value(a, value());
  } else if (r.cmd == "convert" && a == "--bonn-camera") {
    r.bonn_camera = true;
  } else if (a == "--timestamps") {
    r.timestamps = value();
  } else {
    return false;
  }
  return true;
}

/// Parses argv (the caller has handled --help and --version). Throws UsageError for an unknown
/// command or option, ds3d::InvalidArgument for a bad value.
Args parse(int argc, char** argv) {
  if (argc < 4) throw UsageError{"expected a command and two files"};
  Args r;
  r.cmd = argv[1];
  if (r.cmd != "ate" && r.cmd != "rpe" && r.cmd != "convert") {
    throw UsageError{"unknown command '" + r.cmd + "'"};
  }
  r.files = {argv[2], argv[3]};
  for (int i = 4; i < argc; ++i) {
    const std::string a = argv[i];
    const std::function<std::string()> value = [&]() -> std::string {
      if (i + 1 >= argc) throw ds3d::InvalidArgument(a + " needs a value");
      return argv[++i];
    };
    if (r.cmd != "convert" && a.rfind("--", 0) != 0) {
      r.files.push_back(a);  // one more estimate
    } else if (!(r.cmd != "convert" && metric_option(r, a, value)) && !format_option(r, a, value)) {
      throw UsageError{"unknown option '" + a + "' for " + r.cmd};
    }
  }
  return r;
}

/// Reads a trajectory, printing one warning line per kind of skipped line (NaN/inf values,
/// 0 0 0 0 quaternions): the evaluation would otherwise see fewer poses without a word.
ds3d::Trajectory read_checked(const Args& args, const std::string& path,
                              std::optional<ds3d::TrajectoryFormat> format,
                              bool keep_zero_quaternion, const char* zero_note) {
  ds3d::TrajectoryReadOptions o{.format = format, .keep_zero_quaternion = keep_zero_quaternion};
  if (!args.timestamps.empty()) o.kitti_timestamps = ds3d::read_timestamp_list(args.timestamps);
  const auto r = ds3d::read_trajectory(path, o);
  if (r.num_non_finite > 0) {
    std::cerr << "ds3d-eval: warning: " << path << ": " << r.num_non_finite << " of " << r.num_lines
              << " line(s) skipped for a NaN or infinite value (first: line "
              << r.first_non_finite_line << ")\n";
  }
  if (r.num_zero_quaternion > 0) {
    std::cerr << "ds3d-eval: warning: " << path << ": " << r.num_zero_quaternion << " of "
              << r.num_lines << " line(s) skipped for a 0 0 0 0 quaternion (first: line "
              << r.first_zero_quaternion_line << "; " << zero_note << ")\n";
  }
  return r.trajectory;
}

constexpr const char* kZeroNote = "rpe needs a rotation, ate keeps them";

/// The ATE object of --json (without the file names).
std::string ate_json(const ds3d::AteResult& r, const ds3d::AteOptions& ate) {
  const std::string stats =
      stats_json(ds3d::ErrorStats{r.rmse, r.mean, r.median, r.std, r.min, r.max}, "m");
  // The statistics' members inline (without the closing brace), as before.
  std::string out = "{\"compared_pose_pairs\":" + std::to_string(r.compared_pose_pairs) + "," +
                    stats.substr(1, stats.size() - 2) + ",\"alignment\":{\"rotation\":[";
  for (int k = 0; k < 3; ++k) {
    out += (k ? ",[" : "[");
    for (int j = 0; j < 3; ++j) out += (j ? "," : "") + json_number(r.rotation(k, j));
    out += "]";
  }
  out += "],\"translation\":[";
  for (int k = 0; k < 3; ++k) out += (k ? "," : "") + json_number(r.translation(k));
  out += "],\"scale\":" + json_number(r.scale_factor) +
         ",\"convention\":\"p_gt ~= scale * rotation @ p_est + translation\"}";
  if (ate.window > 0) out += windows_json(r);
  return out + "}";
}

void print_ate(const ds3d::AteResult& r, const ds3d::AteOptions& ate) {
  std::printf("compared_pose_pairs %zu pairs\n", r.compared_pose_pairs);
  print_stats("absolute_translational_error",
              ds3d::ErrorStats{r.rmse, r.mean, r.median, r.std, r.min, r.max}, "m");
  if (ate.alignment == ds3d::Alignment::kSim3) print_line("alignment.scale", r.scale_factor, "");
  if (ate.window > 0) print_windows(r, ate.window);
}

std::string rpe_json(const ds3d::RpeResult& r) {
  return "{\"compared_pose_pairs\":" + std::to_string(r.compared_pose_pairs) +
         ",\"translational\":" + stats_json(r.translational, "m") +
         ",\"rotational\":" + stats_json(r.rotational, "deg") +
         ",\"rotational_rad\":" + stats_json(r.rotational_rad, "rad") +
         ",\"subsampled\":" + (r.subsampled ? "true" : "false") + "}";
}

void print_rpe(const ds3d::RpeResult& r) {
  // evaluate_rpe.py --verbose, except that the median is really in degrees here.
  std::printf("compared_pose_pairs %zu pairs\n", r.compared_pose_pairs);
  print_stats("translational_error", r.translational, "m");
  print_stats("rotational_error", r.rotational, "deg");
}

/// One estimate's JSON object for several estimates: `{"file": ..., <members of one>}`.
std::string with_file(const std::string& path, const std::string& object) {
  return "{\"file\":\"" + ds3d::detail::json_escape(path) + "\"," + object.substr(1);
}

/// ate and rpe over every estimate: one block each (with an `estimate FILE` line before it when
/// there are several), or one JSON object (a list of them in "estimates" for several).
int evaluate(const Args& a) {
  const bool ate = a.cmd == "ate";
  const std::string& gt_path = a.files[0];
  // evaluate_ate.py reads positions only: a 0 0 0 0 quaternion does not drop a line.
  const auto gt = read_checked(a, gt_path, a.gt_format, ate, kZeroNote);
  std::vector<ds3d::AtePlotEstimate> ates;
  std::vector<ds3d::RpeResult> rpes;
  for (std::size_t k = 1; k < a.files.size(); ++k) {
    const std::string& est_path = a.files[k];
    const auto est = read_checked(a, est_path, a.est_format, ate, kZeroNote);
    if (ate) {
      ates.push_back({est_path, with_files(gt_path, est_path,
                                           [&] { return ds3d::evaluate_ate(gt, est, a.ate); })});
    } else {
      rpes.push_back(
          with_files(gt_path, est_path, [&] { return ds3d::evaluate_rpe(gt, est, a.rpe); }));
    }
  }
  if (!a.plot.empty() && ates.size() == 1) {
    ds3d::write_ate_plot(a.plot, gt, ates.front().result,
                         {.title = "ATE  " + a.files[1] + "  vs  " + gt_path});
  } else if (!a.plot.empty()) {
    ds3d::write_multi_ate_plot(a.plot, gt, ates, {.title = "ATE  vs  " + gt_path});
  }
  const std::size_t n = a.files.size() - 1;
  std::string json =
      n > 1 ? "{\"ground_truth\":\"" + ds3d::detail::json_escape(gt_path) + "\",\"estimates\":["
            : "";
  for (std::size_t k = 0; k < n; ++k) {
    if (a.json) {
      const std::string one = ate ? ate_json(ates[k].result, a.ate) : rpe_json(rpes[k]);
      json += n == 1 ? one : (k ? "," : "") + with_file(a.files[k + 1], one);
      continue;
    }
    if (n > 1) std::printf("%sestimate %s\n", k > 0 ? "\n" : "", a.files[k + 1].c_str());
    if (ate) print_ate(ates[k].result, a.ate);
    if (!ate) print_rpe(rpes[k]);
  }
  if (a.json) std::cout << json << (n > 1 ? "]}\n" : "\n");
  return 0;
}

/// convert IN OUT: every pose of IN (zero-quaternion and non-finite lines skipped, with a
/// warning) written to OUT in --to, else the format OUT's extension names.
int convert(const Args& a) {
  auto traj = read_checked(a, a.files[0], a.est_format, false, "a pose needs a rotation");
  if (a.bonn_camera) traj = ds3d::bonn_marker_to_camera(std::move(traj));
  const std::filesystem::path out = a.files[1];
  const ds3d::TrajectoryFormat to = a.to.value_or(
      ds3d::detail::lower(out.extension().string()) == ".csv" ? ds3d::TrajectoryFormat::kEuroc
                                                              : ds3d::TrajectoryFormat::kTum);
  ds3d::write_trajectory(out, traj, to);
  std::printf("%zu poses written to %s (%s%s)\n", traj.size(), out.string().c_str(),
              ds3d::to_string(to), a.bonn_camera ? ", Bonn marker poses -> camera poses" : "");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc == 2 && (std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help")) {
      std::cout << kUsage;
      return 0;
    }
    if (argc == 2 && std::string(argv[1]) == "--version") {
      std::cout << "ds3d-eval " << ds3d::kVersion << "\n";
      return 0;
    }
    const Args a = parse(argc, argv);
    return a.cmd == "convert" ? convert(a) : evaluate(a);
  } catch (const UsageError& e) {
    return usage(e.message);
  } catch (const ds3d::InvalidArgument& e) {
    std::cerr << error_line(e.what()) << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << error_line(e.what()) << "\n";
    return 1;
  }
}
