// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/cluster/hdbscan_predict.hpp (see its documentation). The estimator
// `ds3d.HDBSCAN` and `ds3d.approximate_predict` / `ds3d.membership_vector` with the reference's
// names live in python/ds3d/hdbscan_estimator.py; this file only exposes the C++ class.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstdint>
#include <vector>

#include "ds3d/cluster/hdbscan_predict.hpp"
#include "numpy_util.hpp"

namespace py = pybind11;

using ds3d::py_util::to_numpy;

void bind_hdbscan_predict(py::module_& m) {
  using ds3d::HdbscanPredictor;
  using Query = Eigen::Ref<const ds3d::RowMatrixXd>;
  py::class_<HdbscanPredictor>(m, "HdbscanPredictor",
                               "See ds3d::HdbscanPredictor in ds3d/cluster/hdbscan_predict.hpp; "
                               "ds3d.HDBSCAN.generate_prediction_data() builds one.")
      .def(py::init<Query, const ds3d::HdbscanResult&, const ds3d::HdbscanParams&, int>(),
           py::arg("points"), py::arg("fit"), py::arg("params"), py::arg("num_threads") = 1,
           py::call_guard<py::gil_scoped_release>())
      .def(
          "approximate_predict",
          [](const HdbscanPredictor& p, Query query) {
            ds3d::HdbscanPrediction r;
            {
              py::gil_scoped_release release;
              r = p.approximate_predict(query);
            }
            return py::make_tuple(to_numpy(r.labels), to_numpy(r.probabilities));
          },
          py::arg("query"), "(labels int32, probabilities float64) of new points")
      .def("membership_vector", &HdbscanPredictor::membership_vector, py::arg("query"),
           py::call_guard<py::gil_scoped_release>(), "M x num_labels float64")
      .def("all_points_membership_vectors", &HdbscanPredictor::all_points_membership_vectors,
           py::call_guard<py::gil_scoped_release>(), "N x num_labels float64")
      .def(
          "exemplars",
          [](const HdbscanPredictor& p, int label) { return to_numpy(p.exemplars(label)); },
          py::arg("label"), "uint32 indices of the exemplar points of one label")
      .def_property_readonly("size", &HdbscanPredictor::size)
      .def_property_readonly("dim", &HdbscanPredictor::dim)
      .def_property_readonly("num_labels", &HdbscanPredictor::num_labels)
      .def_property_readonly("min_samples", &HdbscanPredictor::min_samples)
      .def_property_readonly(
          "core_distances", [](const HdbscanPredictor& p) { return to_numpy(p.core_distances()); });
}
