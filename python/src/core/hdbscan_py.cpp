// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/hdbscan.hpp (see its documentation). The Python-facing
// `ds3d.hdbscan(...)` with the reference's keyword names and the structured condensed tree lives
// in python/ds3d/hdbscan.py; this file only exposes the C++ types and calls.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstdint>
#include <vector>

#include "ds3d/cluster/hdbscan.hpp"
#include "numpy_util.hpp"

namespace py = pybind11;

using ds3d::py_util::to_numpy;

void bind_hdbscan(py::module_& m) {
  py::enum_<ds3d::ClusterSelection>(m, "ClusterSelection")
      .value("eom", ds3d::ClusterSelection::kEom)
      .value("leaf", ds3d::ClusterSelection::kLeaf);
  py::enum_<ds3d::MstAlgorithm>(m, "MstAlgorithm")
      .value("auto", ds3d::MstAlgorithm::kAuto)
      .value("prims", ds3d::MstAlgorithm::kPrims)
      .value("boruvka", ds3d::MstAlgorithm::kBoruvka);
  py::class_<ds3d::HdbscanParams>(m, "HdbscanParams",
                                  "See ds3d::HdbscanParams in ds3d/cluster/hdbscan.hpp.")
      .def(py::init<>())
      .def_readwrite("min_cluster_size", &ds3d::HdbscanParams::min_cluster_size)
      .def_readwrite("min_samples", &ds3d::HdbscanParams::min_samples)
      .def_readwrite("cluster_selection_method", &ds3d::HdbscanParams::cluster_selection_method)
      .def_readwrite("allow_single_cluster", &ds3d::HdbscanParams::allow_single_cluster)
      .def_readwrite("cluster_selection_epsilon", &ds3d::HdbscanParams::cluster_selection_epsilon)
      .def_readwrite("max_cluster_size", &ds3d::HdbscanParams::max_cluster_size)
      .def_readwrite("algorithm", &ds3d::HdbscanParams::algorithm)
      .def_readwrite("num_threads", &ds3d::HdbscanParams::num_threads)
      .def_readwrite("reference_tie_order", &ds3d::HdbscanParams::reference_tie_order)
      .def("validate", &ds3d::HdbscanParams::validate);
  py::class_<ds3d::HdbscanResult>(m, "HdbscanResultRaw",
                                  "See ds3d::HdbscanResult; ds3d.hdbscan() wraps it.")
      .def_property_readonly("labels",
                             [](const ds3d::HdbscanResult& r) { return to_numpy(r.labels); })
      .def_property_readonly("probabilities",
                             [](const ds3d::HdbscanResult& r) { return to_numpy(r.probabilities); })
      .def_property_readonly(
          "outlier_scores", [](const ds3d::HdbscanResult& r) { return to_numpy(r.outlier_scores); })
      .def_property_readonly(
          "core_distances", [](const ds3d::HdbscanResult& r) { return to_numpy(r.core_distances); })
      .def_property_readonly(
          "cluster_persistence",
          [](const ds3d::HdbscanResult& r) { return to_numpy(r.cluster_persistence); })
      .def_property_readonly(
          "selected_clusters",
          [](const ds3d::HdbscanResult& r) { return to_numpy(r.selected_clusters); },
          "condensed-tree id of each selected cluster, in label order")
      .def_readonly("num_clusters", &ds3d::HdbscanResult::num_clusters)
      .def_readonly("min_samples_effective", &ds3d::HdbscanResult::min_samples_effective)
      .def_property_readonly(
          "condensed_tree_columns",
          [](const ds3d::HdbscanResult& r) {
            std::vector<std::int64_t> parent, child, size;
            std::vector<double> lambda;
            for (const auto& row : r.condensed_tree) {
              parent.push_back(row.parent);
              child.push_back(row.child);
              lambda.push_back(row.lambda_val);
              size.push_back(row.child_size);
            }
            return py::make_tuple(to_numpy(parent), to_numpy(child), to_numpy(lambda),
                                  to_numpy(size));
          },
          "(parent, child, lambda_val, child_size) arrays")
      .def_property_readonly(
          "single_linkage_tree",
          [](const ds3d::HdbscanResult& r) {
            py::array_t<double> a(
                {static_cast<py::ssize_t>(r.single_linkage_tree.size()), py::ssize_t{4}});
            auto v = a.mutable_unchecked<2>();
            for (std::size_t i = 0; i < r.single_linkage_tree.size(); ++i) {
              const auto& s = r.single_linkage_tree[i];
              const auto k = static_cast<py::ssize_t>(i);
              v(k, 0) = static_cast<double>(s.left);
              v(k, 1) = static_cast<double>(s.right);
              v(k, 2) = s.distance;
              v(k, 3) = static_cast<double>(s.size);
            }
            return a;
          },
          "(n-1) x 4 float64 in scipy linkage layout: left, right, distance, size")
      .def_property_readonly(
          "min_spanning_tree",
          [](const ds3d::HdbscanResult& r) {
            py::array_t<double> a(
                {static_cast<py::ssize_t>(r.min_spanning_tree.size()), py::ssize_t{3}});
            auto v = a.mutable_unchecked<2>();
            for (std::size_t i = 0; i < r.min_spanning_tree.size(); ++i) {
              const auto& e = r.min_spanning_tree[i];
              const auto k = static_cast<py::ssize_t>(i);
              v(k, 0) = e.from;
              v(k, 1) = e.to;
              v(k, 2) = e.weight;
            }
            return a;
          },
          "(n-1) x 3 float64: from, to, weight, sorted by weight");
  m.def(
      "_hdbscan",
      [](Eigen::Ref<const ds3d::RowMatrixXd> points, const ds3d::HdbscanParams& params,
         const std::vector<double>& scale) { return ds3d::hdbscan(points, params, scale); },
      py::arg("points"), py::arg("params"), py::arg("scale") = std::vector<double>{},
      py::call_guard<py::gil_scoped_release>(), "ds3d::hdbscan (see ds3d/cluster/hdbscan.hpp).");
  m.def(
      "_hdbscan_precomputed",
      [](Eigen::Ref<const ds3d::RowMatrixXd> distances, const ds3d::HdbscanParams& params) {
        return ds3d::hdbscan_precomputed(distances, params);
      },
      py::arg("distances"), py::arg("params"), py::call_guard<py::gil_scoped_release>(),
      "ds3d::hdbscan_precomputed (see ds3d/cluster/hdbscan.hpp).");
}
