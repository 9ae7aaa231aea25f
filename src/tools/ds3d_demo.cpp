// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-demo: runs every registered demo step on embedded, generated data (nothing downloaded,
// nothing read from ../shared). Usage: ds3d-demo [--out DIR] [--seed N] [--quick] [--list]
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>

#include "ds3d/slam/build_info.hpp"
#include "ds3d/version.hpp"
#include "ds3d_demo/demo.hpp"

int main(int argc, char** argv) {
  ds3d::demo::Context ctx;
  ctx.out_dir = "demo_out";
  bool list_only = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc) {
      ctx.out_dir = argv[++i];
    } else if (a == "--seed" && i + 1 < argc) {
      // strtoull would take "-1" as 2^64 - 1 and "x" as 0; only a plain decimal is a seed.
      const std::string v = argv[++i];
      const auto r = std::from_chars(v.data(), v.data() + v.size(), ctx.seed);
      if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size()) {
        std::cerr << "ds3d-demo: --seed expects an integer in [0, 18446744073709551615] (got '" << v
                  << "')\n";
        return 2;
      }
    } else if (a == "--quick") {
      ctx.quick = true;
    } else if (a == "--list") {
      list_only = true;
    } else if (a == "-h" || a == "--help") {
      std::cout << "usage: ds3d-demo [--out DIR] [--seed N] [--quick] [--list]\n"
                   "       ds3d-demo --version\n";
      return 0;
    } else if (a == "--version") {
      std::cout << "ds3d-demo " << ds3d::kVersion << "\n";
      return 0;
    } else {
      std::cerr << "ds3d-demo: unknown argument '" << a << "' (try --help)\n";
      return 2;
    }
  }
  auto steps = ds3d::demo::registry();
  std::stable_sort(steps.begin(), steps.end(),
                   [](const auto& a, const auto& b) { return a.order < b.order; });
  if (list_only) {
    for (const auto& s : steps) std::cout << s.order << " " << s.name << "\n";
    return 0;
  }
  std::filesystem::create_directories(ctx.out_dir);
  std::cout << ds3d::build_info_string() << "\n";
  std::cout << "output directory: " << std::filesystem::absolute(ctx.out_dir).string() << "\n";
  int failures = 0;
  for (const auto& s : steps) {
    std::cout << "\n== " << s.name << " ==\n";
    const auto t0 = std::chrono::steady_clock::now();
    try {
      s.run(ctx);
    } catch (const std::exception& e) {
      std::cout << "step '" << s.name << "' failed: " << e.what() << "\n";
      ++failures;
    }
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "(" << s.name << ": " << ms << " ms)\n";
  }
  std::cout << "\n"
            << steps.size() - static_cast<std::size_t>(failures) << " of " << steps.size()
            << " demo steps succeeded\n";
  return failures == 0 ? 0 : 1;
}
