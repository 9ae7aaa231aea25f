// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// ds3d-demo: each src/tools/ds3d_demo/<step>.cpp registers one step with DS3D_DEMO_STEP; the demo
// runs them in order of their number. Steps print what they did with real figures.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

namespace ds3d::demo {

struct Context {
  std::filesystem::path out_dir;  ///< where steps may write files (created by main)
  std::uint64_t seed = 1;         ///< for anything randomised
  bool quick = false;             ///< smaller sizes (tests)
};

struct Step {
  int order;
  std::string name;
  std::function<void(const Context&)> run;
};

inline std::vector<Step>& registry() {
  static std::vector<Step> steps;
  return steps;
}

struct Registrar {
  Registrar(int order, std::string name, std::function<void(const Context&)> run) {
    registry().push_back({order, std::move(name), std::move(run)});
  }
};

}  // namespace ds3d::demo

#define DS3D_DEMO_CONCAT2(a, b) a##b
#define DS3D_DEMO_CONCAT(a, b) DS3D_DEMO_CONCAT2(a, b)
/// Registers a demo step: DS3D_DEMO_STEP(20, "preprocess", [](const ds3d::demo::Context& c){...});
#define DS3D_DEMO_STEP(order, name, fn) \
  static const ::ds3d::demo::Registrar DS3D_DEMO_CONCAT(ds3d_demo_step_, __LINE__)(order, name, fn)
