// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-eval: ATE and RPE of a TUM-format estimate against ground truth, with the numbers of the
// TUM benchmark scripts (evaluate_ate.py / evaluate_rpe.py --verbose) or one JSON object.
// ate --window W adds the local ATE: the pairs cut into W-second windows, each aligned alone.
//   ds3d-eval ate GT EST [--max-difference 0.02] [--offset 0] [--scale 1] [--align se3|sim3|none]
//                        [--window SECONDS] [--plot out.png] [--json]
//   ds3d-eval rpe GT EST [--delta 1] [--delta-unit s|f|m|rad|deg] [--offset 0] [--scale 1]
//                        [--all-pairs] [--max-pairs 10000] [--evo] [--seed 1] [--json]
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "ds3d/detail/json.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "ds3d/slam/trajectory_plot.hpp"
#include "ds3d/version.hpp"

namespace {

using ds3d::detail::json_number;

constexpr const char* kUsage =
    "usage: ds3d-eval ate GT EST [--max-difference 0.02] [--offset 0] [--scale 1]\n"
    "                 [--align se3|sim3|none] [--window SECONDS] [--plot out.png]\n"
    "                 [--json]\n"
    "       ds3d-eval rpe GT EST [--delta 1] [--delta-unit s|f|m|rad|deg] [--offset 0]\n"
    "                 [--scale 1] [--all-pairs] [--max-pairs 10000] [--evo] [--seed 1]\n"
    "                 [--json]\n"
    "       ds3d-eval --help | --version\n";

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

/// Reads a TUM file, printing one warning line per kind of skipped line (NaN/inf values,
/// 0 0 0 0 quaternions): the evaluation would otherwise see fewer poses without a word.
ds3d::Trajectory read_checked(const std::string& path, bool keep_zero_quaternion) {
  const auto r = ds3d::read_tum_file(path, {.keep_zero_quaternion = keep_zero_quaternion});
  if (r.num_non_finite > 0) {
    std::cerr << "ds3d-eval: warning: " << path << ": " << r.num_non_finite << " of " << r.num_lines
              << " line(s) skipped for a NaN or infinite value (first: line "
              << r.first_non_finite_line << ")\n";
  }
  if (r.num_zero_quaternion > 0) {
    std::cerr << "ds3d-eval: warning: " << path << ": " << r.num_zero_quaternion << " of "
              << r.num_lines << " line(s) skipped for a 0 0 0 0 quaternion (first: line "
              << r.first_zero_quaternion_line << "; rpe needs a rotation, ate keeps them)\n";
  }
  return r.trajectory;
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
    if (argc < 4) return usage("expected a command and two files");
    const std::string cmd = argv[1];
    if (cmd != "ate" && cmd != "rpe") return usage("unknown command '" + cmd + "'");
    const std::string gt_path = argv[2];
    const std::string est_path = argv[3];
    ds3d::AteOptions ate;
    ds3d::RpeOptions rpe;
    std::string plot;
    bool json = false;
    for (int i = 4; i < argc; ++i) {
      const std::string a = argv[i];
      const auto value = [&]() -> std::string {
        if (i + 1 >= argc) throw ds3d::InvalidArgument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--json") {
        json = true;
      } else if (a == "--offset") {
        ate.offset = rpe.offset = to_double(a, value());
      } else if (a == "--scale") {
        ate.scale = rpe.scale = to_double(a, value());
      } else if (cmd == "ate" && a == "--max-difference") {
        ate.max_difference = to_double(a, value());
      } else if (cmd == "ate" && a == "--align") {
        ate.alignment = ds3d::parse_alignment(value());
      } else if (cmd == "ate" && a == "--window") {
        ate.window = to_double(a, value());
      } else if (cmd == "ate" && a == "--plot") {
        plot = value();
      } else if (cmd == "rpe" && a == "--delta") {
        rpe.delta = to_double(a, value());
      } else if (cmd == "rpe" && a == "--delta-unit") {
        rpe.delta_unit = ds3d::parse_delta_unit(value());
      } else if (cmd == "rpe" && a == "--all-pairs") {
        rpe.fixed_delta = false;
      } else if (cmd == "rpe" && a == "--max-pairs") {
        rpe.max_pairs = static_cast<std::size_t>(to_count(a, value(), 1e12));
      } else if (cmd == "rpe" && a == "--evo") {
        rpe.convention = ds3d::RpeConvention::kEvo;
      } else if (cmd == "rpe" && a == "--seed") {
        rpe.seed = to_count(a, value(), 0x1p53);
      } else {
        return usage("unknown option '" + a + "' for " + cmd);
      }
    }
    if (cmd == "ate") {
      // evaluate_ate.py reads positions only: a 0 0 0 0 quaternion does not drop a line.
      const auto gt = read_checked(gt_path, true);
      const auto est = read_checked(est_path, true);
      const auto r =
          with_files(gt_path, est_path, [&] { return ds3d::evaluate_ate(gt, est, ate); });
      if (!plot.empty()) {
        ds3d::write_ate_plot(plot, gt, r, {.title = "ATE  " + est_path + "  vs  " + gt_path});
      }
      if (json) {
        const std::string stats =
            stats_json(ds3d::ErrorStats{r.rmse, r.mean, r.median, r.std, r.min, r.max}, "m");
        // The statistics' members inline (without the closing brace), as before.
        std::string out = "{\"compared_pose_pairs\":" + std::to_string(r.compared_pose_pairs) +
                          "," + stats.substr(1, stats.size() - 2) +
                          ",\"alignment\":{\"rotation\":[";
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
        std::cout << out << "}\n";
      } else {
        std::printf("compared_pose_pairs %zu pairs\n", r.compared_pose_pairs);
        print_stats("absolute_translational_error",
                    ds3d::ErrorStats{r.rmse, r.mean, r.median, r.std, r.min, r.max}, "m");
        if (ate.alignment == ds3d::Alignment::kSim3)
          print_line("alignment.scale", r.scale_factor, "");
        if (ate.window > 0) print_windows(r, ate.window);
      }
    } else {
      const auto gt = read_checked(gt_path, false);
      const auto est = read_checked(est_path, false);
      const auto r =
          with_files(gt_path, est_path, [&] { return ds3d::evaluate_rpe(gt, est, rpe); });
      if (json) {
        std::cout << "{\"compared_pose_pairs\":" << r.compared_pose_pairs
                  << ",\"translational\":" << stats_json(r.translational, "m")
                  << ",\"rotational\":" << stats_json(r.rotational, "deg")
                  << ",\"rotational_rad\":" << stats_json(r.rotational_rad, "rad")
                  << ",\"subsampled\":" << (r.subsampled ? "true" : "false") << "}\n";
      } else {
        // evaluate_rpe.py --verbose, except that the median is really in degrees here.
        std::printf("compared_pose_pairs %zu pairs\n", r.compared_pose_pairs);
        print_stats("translational_error", r.translational, "m");
        print_stats("rotational_error", r.rotational, "deg");
      }
    }
    return 0;
  } catch (const ds3d::InvalidArgument& e) {
    std::cerr << error_line(e.what()) << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << error_line(e.what()) << "\n";
    return 1;
  }
}
