// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/sparse_detector.hpp (see that header for the documentation).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <string>
#include <vector>

#include "ds3d/htx/sparse_detector.hpp"
#include "numpy_util.hpp"

namespace py = pybind11;

namespace {
using Rows = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// (M, 9) float32: cx, cy, cz, dx, dy, dz, yaw, score, class.
Rows to_rows(const std::vector<ds3d::Box3>& boxes) {
  Rows r(static_cast<Eigen::Index>(boxes.size()), 9);
  for (Eigen::Index i = 0; i < r.rows(); ++i) {
    const auto& b = boxes[static_cast<std::size_t>(i)];
    r.row(i) << b.centre.x(), b.centre.y(), b.centre.z(), b.size.x(), b.size.y(), b.size.z(), b.yaw,
        b.score, static_cast<float>(b.label);
  }
  return r;
}
using PointsF32 = py::array_t<float, py::array::c_style | py::array::forcecast>;

// The (n, 3) float32 points of `obj` (no copy for a C-contiguous float32 array); ValueError naming
// `function`, the parameter and the shape/dtype for anything else (pybind11 says TypeError).
PointsF32 points_f32(const char* function, const py::handle& obj) {
  ds3d::py_util::check_points(function, obj);
  return PointsF32::ensure(obj);
}

Eigen::Map<const ds3d::Points3f> view(const PointsF32& a) {
  return {a.data(), static_cast<Eigen::Index>(a.shape(0)), 3};
}
}  // namespace

void bind_sparse_detector(py::module_& m) {
  py::class_<ds3d::DetectorConfig>(m, "DetectorConfig",
                                   "HTx-lite configuration (include/ds3d/sparse_detector.hpp)")
      .def_readonly("profile", &ds3d::DetectorConfig::profile)
      .def_readonly("num_centres", &ds3d::DetectorConfig::num_centres)
      .def_readonly("sa_radius", &ds3d::DetectorConfig::sa_radius)
      .def_readonly("sa_samples", &ds3d::DetectorConfig::sa_samples)
      .def_readonly("sa_mlp", &ds3d::DetectorConfig::sa_mlp)
      .def_readonly("d_model", &ds3d::DetectorConfig::d_model)
      .def_readonly("num_heads", &ds3d::DetectorConfig::num_heads)
      .def_readonly("enc_layers", &ds3d::DetectorConfig::enc_layers)
      .def_readonly("enc_ffn", &ds3d::DetectorConfig::enc_ffn)
      .def_readonly("dec_layers", &ds3d::DetectorConfig::dec_layers)
      .def_readonly("dec_ffn", &ds3d::DetectorConfig::dec_ffn)
      .def_readonly("num_queries", &ds3d::DetectorConfig::num_queries)
      .def_readonly("num_classes", &ds3d::DetectorConfig::num_classes)
      .def_readonly("class_names", &ds3d::DetectorConfig::class_names)
      .def_readonly("num_angle_bins", &ds3d::DetectorConfig::num_angle_bins)
      .def_readonly("head_hidden", &ds3d::DetectorConfig::head_hidden)
      .def_readonly("part_hidden", &ds3d::DetectorConfig::part_hidden)
      .def_readonly("layer_norm_eps", &ds3d::DetectorConfig::layer_norm_eps)
      .def_readonly("min_points_in_box", &ds3d::DetectorConfig::min_points_in_box)
      .def_readonly("nms_iou", &ds3d::DetectorConfig::nms_iou)
      .def_readonly("score_threshold", &ds3d::DetectorConfig::score_threshold)
      .def_readonly("min_size_extent", &ds3d::DetectorConfig::min_size_extent)
      .def_readonly("fps_padding_norm2", &ds3d::DetectorConfig::fps_padding_norm2)
      .def("__repr__", [](const ds3d::DetectorConfig& c) {
        return "<ds3d.DetectorConfig profile='" + c.profile +
               "' num_centres=" + std::to_string(c.num_centres) +
               " d_model=" + std::to_string(c.d_model) +
               " num_queries=" + std::to_string(c.num_queries) +
               " num_classes=" + std::to_string(c.num_classes) + ">";
      });

  py::class_<ds3d::SparseDetector>(
      m, "SparseDetector",
      "HTx-lite detector, Eigen inference (include/ds3d/sparse_detector.hpp).\n"
      "Build with SparseDetector.load(path) from a file written by ds3d.htx.export.")
      .def_static("load", &ds3d::SparseDetector::load, py::arg("path"),
                  "Loads a ds3d-htx weights file; RuntimeError naming the tensor on any defect.")
      .def_property_readonly("config", &ds3d::SparseDetector::config)
      .def(
          "detect",
          [](const ds3d::SparseDetector& d, const py::object& points, int num_threads) {
            const PointsF32 xyz = points_f32("ds3d.SparseDetector.detect", points);
            std::vector<ds3d::Box3> boxes;
            {
              py::gil_scoped_release release;
              boxes = d.detect(view(xyz), num_threads);
            }
            return to_rows(boxes);
          },
          py::arg("points"), py::arg("num_threads") = 1,
          "Boxes of one preprocessed, gravity-aligned cloud (n, 3) float32 as an (M, 9) float32 "
          "array:\n"
          "cx, cy, cz, dx, dy, dz, yaw, score, class (yaw from +X towards -Y; decreasing "
          "objectness).")
      .def(
          "run",
          [](const ds3d::SparseDetector& d, const py::object& points, int num_threads,
             bool part_logits) {
            const PointsF32 xyz = points_f32("ds3d.SparseDetector.run", points);
            ds3d::DetectorOutput o;
            {
              py::gil_scoped_release release;
              o = d.run(view(xyz), {.num_threads = num_threads, .part_logits = part_logits});
            }
            Rows prop = to_rows(o.proposals);
            Eigen::VectorXf obj(static_cast<Eigen::Index>(o.proposals.size()));
            for (std::size_t i = 0; i < o.proposals.size(); ++i)
              obj[static_cast<Eigen::Index>(i)] = o.proposals[i].objectness;
            py::dict r;
            r["boxes"] = to_rows(o.boxes);
            r["centre_indices"] = py::array_t<std::int32_t>(
                static_cast<py::ssize_t>(o.centre_indices.size()), o.centre_indices.data());
            r["query_indices"] = py::array_t<std::int32_t>(
                static_cast<py::ssize_t>(o.query_indices.size()), o.query_indices.data());
            r["proposals"] = prop;
            r["objectness"] = obj;
            r["class_prob"] = Rows(o.class_prob);
            r["part_logits"] = Rows(o.part_logits);
            return r;
          },
          py::arg("points"), py::arg("num_threads") = 1, py::arg("part_logits") = true,
          "Full forward pass: dict with boxes (M, 9), centre_indices, query_indices, proposals (q, "
          "9),\n"
          "objectness (q,), class_prob (q, K) and part_logits (n, 4) (empty unless part_logits).");

  m.def(
      "upright_rotation",
      [](const Eigen::Vector3d& up_cam) { return Eigen::Matrix3f(ds3d::upright_rotation(up_cam)); },
      py::arg("up_cam"),
      "(3, 3) float32 rotation camera -> upright detector frame mapping up_cam (the floor normal "
      "in\n"
      "the camera frame, e.g. PreprocessResult.ground_plane[:3]) to +Z; ValueError for a zero or\n"
      "downward vector. See include/ds3d/sparse_detector.hpp.");
  m.def(
      "make_detector_input",
      [](const Eigen::Ref<const ds3d::Points3f>& cloud_cam, const Eigen::Matrix3f& R_up_cam,
         int num_points, std::uint64_t seed) {
        ds3d::DetectorInput in;
        {
          py::gil_scoped_release release;
          in = ds3d::make_detector_input(cloud_cam, R_up_cam,
                                         {.num_points = num_points, .seed = seed});
        }
        return py::make_tuple(
            ds3d::Points3f(in.points),
            py::array_t<std::uint32_t>(static_cast<py::ssize_t>(in.rows.size()), in.rows.data()));
      },
      py::arg("cloud_cam"), py::arg("R_up_cam"), py::arg("num_points") = 4096, py::arg("seed") = 0,
      "The detector input exactly as ds3d-slam --dynamic htx builds it (htx spec 6.1 step 5):\n"
      "(points (num_points, 3) float32 upright frame, rows (num_points,) uint32 into cloud_cam).\n"
      "The source passes seed mixed with the frame index; see include/ds3d/sparse_detector.hpp.");
}
