// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/slam/config.hpp: the key table and a SlamConfig set and read by key.
// The attribute and dict conveniences of ds3d.SlamConfig live in python/ds3d/config.py.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <string>
#include <tuple>
#include <vector>

#include "ds3d/slam/config.hpp"

namespace py = pybind11;
using ds3d::slam::SlamConfig;

void bind_config(py::module_& m) {
  py::class_<SlamConfig>(m, "_SlamConfig",
                         "Internal: the C++ SlamConfig behind ds3d.SlamConfig (config.hpp).")
      .def(py::init<>())
      .def("set", &SlamConfig::set, py::arg("key"), py::arg("value"),
           "Sets a key from its text form; ValueError names an unknown key or a bad value.")
      .def("get", &SlamConfig::get, py::arg("key"), "The text form of a key.")
      .def("validate", &SlamConfig::validate, "ValueError naming the bad field.")
      .def("apply_file", &ds3d::slam::apply_config_file, py::arg("path"),
           "Applies a YAML or JSON file (RuntimeError: unreadable; ValueError: bad key/value).")
      .def(
          "dump", [](const SlamConfig& c) { return ds3d::slam::dump_config(c); },
          "Every key with its value and help line, as YAML (ds3d-slam --dump-config).")
      .def(
          "frontend_config", [](const SlamConfig& c) { return c.frontend; },
          "A copy of the front-end section as a ds3d.FrontendConfig (for ds3d.Slam).")
      .def("copy", [](const SlamConfig& c) { return SlamConfig(c); });
  m.def(
      "_config_keys",
      [] {
        std::vector<std::tuple<std::string, std::string, std::string>> out;
        for (const auto& k : ds3d::slam::config_keys()) out.emplace_back(k.name, k.type, k.help);
        return out;
      },
      "Internal: (name, type, help) of every configuration key.");
  m.def(
      "_config_markdown", [] { return ds3d::slam::config_markdown(); },
      "Internal: the key table as Markdown (docs/configuration.md).");
}
