// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/errors.hpp. ds3d's exceptions derive from std::invalid_argument and
// std::runtime_error, which pybind11 already maps to ValueError and RuntimeError; these helpers
// only let the Python tests check that mapping end to end.
#include <pybind11/pybind11.h>

#include <string>

#include "ds3d/errors.hpp"

namespace py = pybind11;

void bind_errors(py::module_& m) {
  m.def(
      "_raise_for_test",
      [](const std::string& kind, const std::string& message) {
        if (kind == "invalid_argument") throw ds3d::InvalidArgument(message);
        if (kind == "io") throw ds3d::IoError(message);
        if (kind == "numerical") throw ds3d::NumericalError(message);
        DS3D_CHECK(false,
                   "ds3d._raise_for_test: kind must be invalid_argument, io or numerical (got '",
                   kind, "')");
      },
      py::arg("kind"), py::arg("message"),
      "Throws the named ds3d exception (test helper for the C++ -> Python error mapping).");
}
