// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/dynamic_filter.hpp (box-gated HDBSCAN dynamic-keypoint filter). See
// the header for the method, units and errors.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>
#include <vector>

#include "../camera_util.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"

namespace py = pybind11;

namespace {

// The camera of DynamicFeatureFilter.filter: `camera`, or the fx fy cx cy width height keywords.
ds3d::PinholeCamera filter_camera(const py::object& camera, const py::object& fx,
                                  const py::object& fy, const py::object& cx, const py::object& cy,
                                  int width, int height) {
  constexpr const char* fn = "ds3d.DynamicFeatureFilter.filter";
  const bool any = !fx.is_none() || !fy.is_none() || !cx.is_none() || !cy.is_none();
  if (!camera.is_none()) {
    DS3D_CHECK(!any, fn, ": give camera or fx, fy, cx, cy, not both");
    return ds3d::py_camera::camera_from(fn, camera);
  }
  if (fx.is_none() || fy.is_none() || cx.is_none() || cy.is_none()) {
    throw py::type_error(std::string(fn) +
                         ": camera is required (a ds3d.Camera, a dict, a preset name or a "
                         "camera.txt path; or the keywords fx, fy, cx, cy)");
  }
  py::dict d;
  d["fx"] = fx;
  d["fy"] = fy;
  d["cx"] = cx;
  d["cy"] = cy;
  d["width"] = width;
  d["height"] = height;
  return ds3d::py_camera::camera_from(fn, d);
}

ds3d::DynamicFilterResult filter(ds3d::DynamicFeatureFilter& f,
                                 Eigen::Ref<const ds3d::Keypoints3f> kp,
                                 const std::vector<ds3d::ImageBox>& boxes, const py::object& camera,
                                 const std::optional<Eigen::Vector4f>& support_plane,
                                 const py::object& fx, const py::object& fy, const py::object& cx,
                                 const py::object& cy, int width, int height) {
  const ds3d::PinholeCamera cam = filter_camera(camera, fx, fy, cx, cy, width, height);
  const py::gil_scoped_release release;
  return f.filter(kp, boxes, cam, support_plane);
}

}  // namespace

void bind_dynamic_filter(py::module_& m) {
  py::class_<ds3d::SolidBox>(m, "SolidBox",
                             "Oriented 3-D box in the camera frame with a metric uncertainty "
                             "(dynamic_filter.hpp): keypoints must lie in it, grown by `margin`.")
      .def(py::init([](const Eigen::Vector3f& centre, const Eigen::Matrix3f& axes,
                       const Eigen::Vector3f& half, float margin) {
             return ds3d::SolidBox{centre, axes, half, margin};
           }),
           py::arg("centre"), py::arg("axes"), py::arg("half"), py::arg("margin") = 0.0F)
      .def_readwrite("centre", &ds3d::SolidBox::centre, "(3,) box centre [m]")
      .def_readwrite("axes", &ds3d::SolidBox::axes, "(3, 3) rows: unit box axes")
      .def_readwrite("half", &ds3d::SolidBox::half, "(3,) half sizes along the axes [m]")
      .def_readwrite("margin", &ds3d::SolidBox::margin, "the box's own uncertainty [m]")
      .def(
          "contains",
          [](const ds3d::SolidBox& b, const Eigen::Vector3f& p, float sigma_z) {
            return b.contains(p, p / p.z(), sigma_z);
          },
          py::arg("point"), py::arg("sigma_z") = 0.0F,
          "True if camera-frame point (z > 0) lies in the box grown by margin + 3σ(z) per axis.");
  m.def(
      "solid_from_corners",
      [](const Eigen::Matrix<float, 8, 3>& corners, float margin, float tol) {
        return ds3d::solid_from_corners(corners, margin, tol);
      },
      py::arg("corners"), py::arg("margin") = 0.0F, py::arg("tol") = 1e-3F,
      "SolidBox of 8 cuboid corners (8, 3) [m] in any order, or None when they are not a cuboid.");
  py::class_<ds3d::ImageBox>(m, "ImageBox", "Image box [px] with optional depth range [m].")
      .def(py::init([](float x_min, float y_min, float x_max, float y_max, float score, int label,
                       float z_min, float z_max) {
             return ds3d::ImageBox{x_min, y_min, x_max, y_max, score, label, z_min, z_max};
           }),
           py::arg("x_min"), py::arg("y_min"), py::arg("x_max"), py::arg("y_max"),
           py::arg("score") = 1.0F, py::arg("label") = -1, py::arg("z_min") = 0.0F,
           py::arg("z_max") = 0.0F)
      .def_readwrite("x_min", &ds3d::ImageBox::x_min)
      .def_readwrite("y_min", &ds3d::ImageBox::y_min)
      .def_readwrite("x_max", &ds3d::ImageBox::x_max)
      .def_readwrite("y_max", &ds3d::ImageBox::y_max)
      .def_readwrite("score", &ds3d::ImageBox::score)
      .def_readwrite("label", &ds3d::ImageBox::label)
      .def_readwrite("z_min", &ds3d::ImageBox::z_min)
      .def_readwrite("z_max", &ds3d::ImageBox::z_max)
      .def_readwrite("solid", &ds3d::ImageBox::solid,
                     "SolidBox or None: with one, keypoints with depth are gated in 3-D.");
  py::class_<ds3d::DynamicFilterParams>(m, "DynamicFilterParams",
                                        "Parameters of DynamicFeatureFilter (dynamic_filter.hpp).")
      .def(py::init<>())
      .def_readwrite("min_score", &ds3d::DynamicFilterParams::min_score)
      .def_readwrite("box_margin", &ds3d::DynamicFilterParams::box_margin)
      .def_readwrite("min_cluster_size", &ds3d::DynamicFilterParams::min_cluster_size)
      .def_readwrite("min_samples", &ds3d::DynamicFilterParams::min_samples)
      .def_readwrite("min_keypoints", &ds3d::DynamicFilterParams::min_keypoints)
      .def_readwrite("depth_gap", &ds3d::DynamicFilterParams::depth_gap)
      .def_readwrite("max_object_depth", &ds3d::DynamicFilterParams::max_object_depth)
      .def_readwrite("depth_noise", &ds3d::DynamicFilterParams::depth_noise)
      .def_readwrite("min_vertical_span", &ds3d::DynamicFilterParams::min_vertical_span)
      .def_readwrite("carry_frames", &ds3d::DynamicFilterParams::carry_frames)
      .def_readwrite("carry_iou", &ds3d::DynamicFilterParams::carry_iou)
      .def_readwrite("carry_motion", &ds3d::DynamicFilterParams::carry_motion)
      .def_readwrite("support_margin", &ds3d::DynamicFilterParams::support_margin)
      .def("validate", &ds3d::DynamicFilterParams::validate);
  py::class_<ds3d::DynamicFilterResult>(m, "DynamicFilterResult")
      .def_readonly("dynamic", &ds3d::DynamicFilterResult::dynamic)
      .def_readonly("gated", &ds3d::DynamicFilterResult::gated)
      .def_readonly("num_dynamic", &ds3d::DynamicFilterResult::num_dynamic)
      .def_readonly("num_non_finite", &ds3d::DynamicFilterResult::num_non_finite)
      .def_readonly("num_ignored_boxes", &ds3d::DynamicFilterResult::num_ignored_boxes)
      .def_readonly("num_on_support", &ds3d::DynamicFilterResult::num_on_support)
      .def_readonly("num_outside_solid", &ds3d::DynamicFilterResult::num_outside_solid);
  py::class_<ds3d::DynamicFeatureFilter>(m, "DynamicFeatureFilter",
                                         "Box-gated HDBSCAN dynamic-keypoint filter; keeps "
                                         "regions across frames (dynamic_filter.hpp).")
      .def(py::init<const ds3d::DynamicFilterParams&>(),
           py::arg("params") = ds3d::DynamicFilterParams{})
      .def("filter", &filter, py::arg("keypoints"), py::arg("boxes"),
           py::arg("camera") = py::none(), py::arg("support_plane") = py::none(), py::kw_only(),
           py::arg("fx") = py::none(), py::arg("fy") = py::none(), py::arg("cx") = py::none(),
           py::arg("cy") = py::none(), py::arg("width") = 640, py::arg("height") = 480,
           "keypoints: N x 3 float32 (u px, v px, depth m; 0 = none); boxes: list of ImageBox;\n"
           "camera: a ds3d.Camera, a dict, a preset name or a camera.txt path (or, instead,\n"
           "the keywords fx fy cx cy [px] with width height [px]); support_plane: (4,) floor\n"
           "(a, b, c, d) in the camera frame, keypoints on it stay static. Returns\n"
           "DynamicFilterResult. TypeError without a camera; ValueError for bad values.")
      .def("reset", &ds3d::DynamicFeatureFilter::reset);
}
