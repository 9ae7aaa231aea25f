// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Binding for include/ds3d/slam/trajectory_plot.hpp: ds3d.plot_ate (the PNG of ds3d-eval ate
// --plot) as a numpy image, optionally written to a file.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>

#include "../trajectory_util.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "ds3d/slam/trajectory_plot.hpp"
#include "slam_py_util.hpp"

namespace py = pybind11;
namespace pu = ds3d::py_slam;

namespace {

// An (n, 8) array, or a TUM file read as ds3d-eval reads it (a 0 0 0 0 quaternion is kept).
ds3d::Trajectory trajectory_from(const char* param, const py::object& obj) {
  if (py::isinstance<py::str>(obj) || py::hasattr(obj, "__fspath__")) {
    return ds3d::read_tum_file(pu::path_from(obj), {.keep_zero_quaternion = true}).trajectory;
  }
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  DS3D_CHECK(a && a.ndim() == 2 && a.shape(1) == 8, "ds3d.plot_ate: ", param,
             " must be an (n, 8) array [t tx ty tz qx qy qz qw] or a TUM file path (got ",
             pu::describe(obj), ")");
  const Eigen::Map<const ds3d::py_traj::Rows> rows(a.data(), a.shape(0), 8);
  return ds3d::py_traj::from_rows(rows, "ds3d.plot_ate");
}

py::array_t<std::uint8_t> plot_ate(const py::object& gt, const py::object& est,
                                   const py::object& path, const std::string& title, int width,
                                   int height, double max_difference, double offset, double scale,
                                   const std::string& align, double window) {
  const auto g = trajectory_from("gt", gt);
  const auto e = trajectory_from("est", est);
  const ds3d::AteOptions o{max_difference, offset, scale, ds3d::parse_alignment(align), window};
  const ds3d::AtePlotOptions po{.width = width, .height = height, .title = title};
  const std::optional<std::string> file =
      path.is_none() ? std::nullopt : std::optional<std::string>(pu::path_from(path));
  cv::Mat image;
  {
    const py::gil_scoped_release release;
    const auto r = ds3d::evaluate_ate(g, e, o);
    image = ds3d::render_ate_plot(g, r, po);
    if (file) ds3d::write_ate_plot(*file, g, r, po);
  }
  return pu::mat_to_array<std::uint8_t>(image);
}

}  // namespace

void bind_trajectory_plot(py::module_& m) {
  m.def("plot_ate", &plot_ate, py::arg("gt"), py::arg("est"), py::arg("path") = py::none(),
        py::kw_only(), py::arg("title") = "", py::arg("width") = 1400, py::arg("height") = 640,
        py::arg("max_difference") = 0.02, py::arg("offset") = 0.0, py::arg("scale") = 1.0,
        py::arg("align") = "se3", py::arg("window") = 0.0,
        "The ATE plot of ds3d-eval ate --plot: left the top view of the ground truth (grey) and\n"
        "the aligned estimate coloured by its error, right the error over time with the RMSE\n"
        "(and the local ATE per window when window > 0 [s]). gt, est: (n, 8) arrays [t tx ty tz\n"
        "qx qy qz qw] (e.g. ds3d.run_slam's result) or TUM file paths; the ATE options are those\n"
        "of ds3d.evaluate_ate. Returns the (height, width, 3) uint8 BGR image; with path, also\n"
        "writes it as PNG (temporary file + rename). ValueError for bad options or no matching\n"
        "stamps; RuntimeError when a file cannot be read or written.");
}
