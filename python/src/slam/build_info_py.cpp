// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/build_info.hpp.
#include <pybind11/pybind11.h>

#include "ds3d/slam/build_info.hpp"

namespace py = pybind11;

void bind_build_info(py::module_& m) {
  py::class_<ds3d::BuildInfo>(m, "BuildInfo", "Versions the compiled library was built with.")
      .def_readonly("ds3d_version", &ds3d::BuildInfo::ds3d_version)
      .def_readonly("opencv_version", &ds3d::BuildInfo::opencv_version)
      .def_readonly("ceres_version", &ds3d::BuildInfo::ceres_version)
      .def_readonly("eigen_version", &ds3d::BuildInfo::eigen_version)
      .def_readonly("compiler", &ds3d::BuildInfo::compiler)
      .def_readonly("debug", &ds3d::BuildInfo::debug)
      .def_readonly("hardware_threads", &ds3d::BuildInfo::hardware_threads)
      .def_readonly("simd", &ds3d::BuildInfo::simd)
      .def_readonly("simd_isa", &ds3d::BuildInfo::simd_isa)
      .def_readonly("eigen_max_align_bytes", &ds3d::BuildInfo::eigen_max_align_bytes)
      .def("__repr__", [](const ds3d::BuildInfo&) { return ds3d::build_info_string(); });
  m.def("build_info", &ds3d::build_info, "Build information (see include/ds3d/build_info.hpp).");
}
