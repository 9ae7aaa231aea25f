// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/ransac_plane.hpp: ds3d.ransac_plane(points, distance_threshold,
// max_iterations=1000, confidence=0.999, seed=0, num_threads=1, normal_prior=None, ...).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <optional>

#include "ds3d/preprocess/ransac_plane.hpp"
#include "numpy_util.hpp"

namespace py = pybind11;

namespace {

template <class Ref>
ds3d::RansacPlaneResult run(const Ref& points, double distance_threshold,
                            std::int64_t max_iterations, double confidence, std::uint64_t seed,
                            int num_threads, std::optional<std::array<double, 3>> normal_prior,
                            double max_angle_deg, bool origin_above) {
  DS3D_CHECK(max_iterations >= 1 && max_iterations <= 0xFFFFFFFFLL,
             "ds3d.ransac_plane: max_iterations must be in [1, 2^32) (got ", max_iterations, ")");
  ds3d::RansacPlaneParams p;
  p.distance_threshold = distance_threshold;
  p.max_iterations = static_cast<std::uint32_t>(max_iterations);
  p.confidence = confidence;
  p.seed = seed;
  p.num_threads = num_threads;
  if (normal_prior) p.normal_prior = {(*normal_prior)[0], (*normal_prior)[1], (*normal_prior)[2]};
  p.max_angle_deg = max_angle_deg;
  p.origin_above = origin_above;
  const py::gil_scoped_release release;
  return ds3d::ransac_plane(points, p);
}

template <class Ref>
void def_overload(py::module_& m, bool noconvert, const char* doc) {
  m.def("_ransac_plane", &run<Ref>, py::arg("points").noconvert(noconvert),
        py::arg("distance_threshold"), py::arg("max_iterations") = 1000,
        py::arg("confidence") = 0.999, py::arg("seed") = 0, py::arg("num_threads") = 1,
        py::arg("normal_prior") = py::none(), py::arg("max_angle_deg") = 20.0,
        py::arg("origin_above") = false, doc);
}

}  // namespace

void bind_ransac_plane(py::module_& m) {
  py::class_<ds3d::RansacPlaneResult>(m, "RansacPlaneResult",
                                      "Output of ransac_plane (include/ds3d/ransac_plane.hpp).")
      .def_readonly("found", &ds3d::RansacPlaneResult::found)
      .def_readonly("plane", &ds3d::RansacPlaneResult::plane, "(a, b, c, d), |(a, b, c)| = 1")
      .def_property_readonly(
          "inliers",
          [](const ds3d::RansacPlaneResult& r) { return ds3d::py_util::to_numpy(r.inliers); },
          "(K,) uint32 ascending input indices with |distance| < distance_threshold")
      .def_readonly("iterations", &ds3d::RansacPlaneResult::iterations)
      .def_readonly("num_non_finite", &ds3d::RansacPlaneResult::num_non_finite)
      .def("__repr__", [](const ds3d::RansacPlaneResult& r) {
        return std::string("<RansacPlaneResult found=") + (r.found ? "True" : "False") +
               " inliers=" + std::to_string(r.inliers.size()) + ">";
      });
  const char* doc =
      "RANSAC plane with least-squares refit and inlier re-selection (see\n"
      "include/ds3d/ransac_plane.hpp). confidence=1.0 disables the early stop. normal_prior:\n"
      "optional up vector; max_angle_deg its tolerance; origin_above: the origin must lie on the\n"
      "up side (a floor below the camera). Raises ValueError on bad parameters.";
  def_overload<Eigen::Ref<const ds3d::Points3f>>(m, true, doc);
  def_overload<Eigen::Ref<const ds3d::Points3d>>(m, true, doc);
  def_overload<Eigen::Ref<const ds3d::Points3d>>(m, false, doc);
  ds3d::py_util::def_checked(m, "ransac_plane", "_ransac_plane", doc);
}
