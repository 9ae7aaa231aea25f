// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/radius_outlier.hpp: ds3d.remove_radius_outliers(points, radius,
// min_neighbors, num_threads=1, search="grid"); search is "grid" or "kdtree".
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>

#include "ds3d/preprocess/radius_outlier.hpp"
#include "numpy_util.hpp"

namespace py = pybind11;

namespace {

template <class Ref>
ds3d::RadiusOutlierResult run(const Ref& points, double radius, std::int64_t min_neighbors,
                              int num_threads, const std::string& search) {
  DS3D_CHECK(min_neighbors >= 0 && min_neighbors <= 0xFFFFFFFFLL,
             "ds3d.remove_radius_outliers: min_neighbors must be in [0, 2^32) (got ", min_neighbors,
             ")");
  DS3D_CHECK(search == "grid" || search == "kdtree",
             "ds3d.remove_radius_outliers: search must be \"grid\" or \"kdtree\" (got \"", search,
             "\")");
  ds3d::RadiusOutlierParams p;
  p.search = search == "grid" ? ds3d::RadiusSearch::kGrid : ds3d::RadiusSearch::kKdTree;
  p.radius = radius;
  p.min_neighbors = static_cast<std::uint32_t>(min_neighbors);
  p.num_threads = num_threads;
  const py::gil_scoped_release release;
  return ds3d::remove_radius_outliers(points, p);
}

}  // namespace

void bind_radius_outlier(py::module_& m) {
  py::class_<ds3d::RadiusOutlierResult>(m, "RadiusOutlierResult",
                                        "Output of remove_radius_outliers "
                                        "(include/ds3d/radius_outlier.hpp).")
      .def_property_readonly(
          "kept",
          [](const ds3d::RadiusOutlierResult& r) { return ds3d::py_util::to_numpy(r.kept); },
          "(K,) uint32 ascending input indices of kept points")
      .def_readonly("num_non_finite", &ds3d::RadiusOutlierResult::num_non_finite)
      .def("__repr__", [](const ds3d::RadiusOutlierResult& r) {
        return "<RadiusOutlierResult kept=" + std::to_string(r.kept.size()) + ">";
      });
  const char* doc =
      "Keep points with >= min_neighbors other finite points within radius (<=, in double).\n"
      "See include/ds3d/radius_outlier.hpp. points: (N, 3) float32 or float64.\n"
      "search: \"grid\" (default) or \"kdtree\" (nanoflann); both keep the same points.\n"
      "Raises ValueError on bad parameters.";
  m.def("_remove_radius_outliers", &run<Eigen::Ref<const ds3d::Points3f>>,
        py::arg("points").noconvert(), py::arg("radius"), py::arg("min_neighbors"),
        py::arg("num_threads") = 1, py::arg("search") = "grid", doc);
  m.def("_remove_radius_outliers", &run<Eigen::Ref<const ds3d::Points3d>>,
        py::arg("points").noconvert(), py::arg("radius"), py::arg("min_neighbors"),
        py::arg("num_threads") = 1, py::arg("search") = "grid", doc);
  m.def("_remove_radius_outliers", &run<Eigen::Ref<const ds3d::Points3d>>, py::arg("points"),
        py::arg("radius"), py::arg("min_neighbors"), py::arg("num_threads") = 1,
        py::arg("search") = "grid", doc);
  ds3d::py_util::def_checked(m, "remove_radius_outliers", "_remove_radius_outliers", doc);
}
