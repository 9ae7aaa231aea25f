// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-synth OUT_DIR --scenario NAME --frames N --seed S [--humans K] [--fps F] [--parts]
//            [--no-noise] [--room X,Y,Z] [--furniture N] [--detection-errors MISS,FALSE]
//            [--overwrite]: writes a synthetic dynamic RGB-D sequence in TUM layout.
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "ds3d/slam/synth.hpp"
#include "ds3d/version.hpp"

namespace {

void print_usage(std::ostream& os) {
  os << "usage: ds3d-synth OUT_DIR [--scenario NAME] [--frames N] [--seed S] [--humans K]\n"
     << "                  [--fps F] [--parts] [--no-noise] [--room X,Y,Z] [--furniture N]\n"
     << "                  [--detection-errors MISS,FALSE] [--overwrite]\n"
     << "       ds3d-synth --help | --version\n"
     << "scenarios: static_room walking_static walking_xyz walking_halfsphere walking_rpy\n"
     << "           sitting_static sitting_xyz crowd_cross crowd_board crowd_start\n"
     << "           crowd_handheld\n"
     << "--detection-errors: also write detections_noisy.jsonl, person boxes missed with\n"
     << "           probability MISS per frame (in runs) and a false box with probability\n"
     << "           FALSE per frame\n"
     << "--overwrite: replace a non-empty OUT_DIR (refused otherwise); the sequence is\n"
     << "           written to a hidden sibling folder and renamed into place at the end\n";
}

int usage(const char* msg) {
  std::cerr << "ds3d-synth: " << msg << "\n";
  print_usage(std::cerr);
  return 2;
}

// One finite number; the whole of `v` must be used.
double parse_double(const std::string& flag, const std::string& v) {
  double x = 0;
  const auto r = std::from_chars(v.data(), v.data() + v.size(), x);
  if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size() || !std::isfinite(x)) {
    throw std::invalid_argument(flag + ": expected a finite number, got '" + v + "'");
  }
  return x;
}

// "A,B,..." as n numbers.
std::vector<double> parse_list(const std::string& flag, const std::string& v, int n) {
  std::vector<double> out;
  std::size_t pos = 0;
  for (int k = 0; k < n; ++k) {
    const std::size_t end = k + 1 < n ? v.find(',', pos) : v.size();
    if (end == std::string::npos)
      throw std::invalid_argument(flag + ": expected " + std::to_string(n) +
                                  " comma-separated numbers, got '" + v + "'");
    out.push_back(parse_double(flag, v.substr(pos, end - pos)));
    pos = end + 1;
  }
  return out;
}

// An integer of type T (range checked: 2^40 for an int is an error, not a wrapped value).
template <class T>
T parse_int(const std::string& flag, const std::string& v) {
  T x = 0;
  const auto r = std::from_chars(v.data(), v.data() + v.size(), x);
  if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size()) {
    throw std::invalid_argument(
        flag + ": expected an integer in [" + std::to_string(std::numeric_limits<T>::min()) + ", " +
        std::to_string(std::numeric_limits<T>::max()) + "], got '" + v + "'");
  }
  return x;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::string out;
    ds3d::synth::SynthOptions opt;
    bool overwrite = false;
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      const auto value = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--scenario") {
        opt.scenario = ds3d::synth::parse_scenario(value());
      } else if (a == "--frames") {
        opt.num_frames = parse_int<int>(a, value());
      } else if (a == "--seed") {
        opt.seed = parse_int<std::uint64_t>(a, value());
      } else if (a == "--humans") {
        opt.num_humans = parse_int<int>(a, value());
      } else if (a == "--fps") {
        opt.fps = parse_double(a, value());
      } else if (a == "--parts") {
        opt.write_parts = true;
      } else if (a == "--room") {
        const std::vector<double> xyz = parse_list(a, value(), 3);
        opt.room_size = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
      } else if (a == "--detection-errors") {
        const std::vector<double> mf = parse_list(a, value(), 2);
        opt.detection_miss = mf[0];
        opt.detection_false = mf[1];
      } else if (a == "--furniture") {
        opt.extra_furniture = parse_int<int>(a, value());
      } else if (a == "--overwrite") {
        overwrite = true;
      } else if (a == "--no-noise") {
        opt.depth_noise = false;
      } else if (a == "--version") {
        std::cout << "ds3d-synth " << ds3d::kVersion << "\n";
        return 0;
      } else if (a == "-h" || a == "--help") {
        print_usage(std::cout);
        return 0;
      } else if (!a.empty() && a[0] == '-') {
        return usage(("unknown option " + a).c_str());
      } else if (out.empty()) {
        out = a;
      } else {
        return usage("more than one OUT_DIR");
      }
    }
    if (out.empty()) return usage("missing OUT_DIR");
    const auto s = ds3d::synth::generate_sequence(out, opt, overwrite);
    std::cout << "ds3d-synth: wrote " << s.frames << " frames of "
              << ds3d::synth::scenario_name(opt.scenario) << " (seed " << opt.seed << ") to " << out
              << "\n  render " << 1e3 * s.render_seconds / static_cast<double>(s.frames)
              << " ms/frame, total " << 1e3 * s.total_seconds / static_cast<double>(s.frames)
              << " ms/frame (with PNG writing), dynamic pixels/frame "
              << s.dynamic_pixels / s.frames << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "ds3d-synth: error: " << e.what() << "\n";
    return 1;
  }
}
