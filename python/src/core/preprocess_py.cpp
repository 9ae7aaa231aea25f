// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/preprocess.hpp: ds3d.preprocess(depth, fx, fy, cx, cy, ...).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <limits>
#include <optional>

#include "../camera_util.hpp"
#include "ds3d/preprocess/preprocess.hpp"
#include "numpy_util.hpp"

namespace py = pybind11;

namespace {

ds3d::PreprocessResult run(
    const Eigen::Ref<const ds3d::DepthImageU16, 0, Eigen::OuterStride<>>& depth, double fx,
    double fy, double cx, double cy, double depth_scale, double leaf_size, int stride,
    double min_depth, double max_depth, bool remove_ground, double ground_threshold,
    std::int64_t ground_max_iterations, std::optional<std::array<double, 3>> ground_normal_prior,
    double ground_max_angle_deg, bool remove_outliers, double outlier_radius,
    std::int64_t outlier_min_neighbors, int num_threads) {
  const char* fn = "ds3d.preprocess";
  DS3D_CHECK(
      depth.rows() > 0 && depth.cols() > 0 && depth.rows() < (1 << 20) && depth.cols() < (1 << 20),
      fn, ": depth must be a non-empty (H, W) uint16 image (got ", depth.rows(), "x", depth.cols(),
      ")");
  DS3D_CHECK(ground_max_iterations >= 1 && ground_max_iterations <= 0xFFFFFFFFLL, fn,
             ": ground_max_iterations must be in [1, 2^32) (got ", ground_max_iterations, ")");
  DS3D_CHECK(outlier_min_neighbors >= 0 && outlier_min_neighbors <= 0xFFFFFFFFLL, fn,
             ": outlier_min_neighbors must be in [0, 2^32) (got ", outlier_min_neighbors, ")");
  ds3d::PinholeCamera cam;
  cam.width = static_cast<int>(depth.cols());
  cam.height = static_cast<int>(depth.rows());
  cam.fx = fx;
  cam.fy = fy;
  cam.cx = cx;
  cam.cy = cy;
  cam.depth_scale = depth_scale;
  ds3d::PreprocessParams p;
  p.depth.stride = stride;
  p.depth.min_depth = min_depth;
  p.depth.max_depth = max_depth;
  p.voxel.leaf_size = leaf_size;
  p.remove_ground = remove_ground;
  p.ground.distance_threshold = ground_threshold;
  p.ground.max_iterations = static_cast<std::uint32_t>(ground_max_iterations);
  p.ground.normal_prior =
      ground_normal_prior ? Eigen::Vector3d((*ground_normal_prior)[0], (*ground_normal_prior)[1],
                                            (*ground_normal_prior)[2])
                          : Eigen::Vector3d::Zero();
  p.ground.origin_above = static_cast<bool>(ground_normal_prior);
  p.ground.max_angle_deg = ground_max_angle_deg;
  p.remove_outliers = remove_outliers;
  p.outlier.radius = outlier_radius;
  p.outlier.min_neighbors = static_cast<std::uint32_t>(outlier_min_neighbors);
  p.num_threads = num_threads;
  const py::gil_scoped_release release;
  return ds3d::preprocess(depth, cam, p);
}

// preprocess with a camera (ds3d.Camera, dict, preset name or camera.txt path) of the image size.
ds3d::PreprocessResult run_camera(
    const Eigen::Ref<const ds3d::DepthImageU16, 0, Eigen::OuterStride<>>& depth,
    const py::object& camera, double leaf_size, int stride, double min_depth, double max_depth,
    bool remove_ground, double ground_threshold, std::int64_t ground_max_iterations,
    std::optional<std::array<double, 3>> ground_normal_prior, double ground_max_angle_deg,
    bool remove_outliers, double outlier_radius, std::int64_t outlier_min_neighbors,
    int num_threads) {
  constexpr const char* fn = "ds3d.preprocess";
  const auto c = ds3d::py_camera::camera_from(fn, camera);
  DS3D_CHECK(depth.rows() == c.height && depth.cols() == c.width, fn, ": depth is ", depth.rows(),
             "x", depth.cols(), " (H x W) but the camera is ", c.height, "x", c.width);
  return run(depth, c.fx, c.fy, c.cx, c.cy, c.depth_scale, leaf_size, stride, min_depth, max_depth,
             remove_ground, ground_threshold, ground_max_iterations, ground_normal_prior,
             ground_max_angle_deg, remove_outliers, outlier_radius, outlier_min_neighbors,
             num_threads);
}

}  // namespace

void bind_preprocess(py::module_& m) {
  using R = ds3d::PreprocessResult;
  py::class_<R>(m, "PreprocessResult", "Output of preprocess (include/ds3d/preprocess.hpp).")
      .def_readonly("points", &R::points, "(M, 3) float32 detector input (voxel centroids)")
      .def_property_readonly(
          "voxel", [](const R& r) { return ds3d::py_util::to_numpy(r.voxel); },
          "(M,) row of each point in the voxel stage")
      .def_property_readonly(
          "source", [](const R& r) { return ds3d::py_util::to_numpy(r.source); },
          "(M,) back-projected point representing each voxel")
      .def_readonly("pixels", &R::pixels, "(M, 2) int32 (u, v) of each source point")
      .def_readonly("ground_found", &R::ground_found)
      .def_readonly("ground_plane", &R::ground_plane)
      .def_readonly("num_input", &R::num_input)
      .def_readonly("num_voxels", &R::num_voxels)
      .def_readonly("num_ground", &R::num_ground)
      .def_readonly("num_outliers", &R::num_outliers)
      .def_readonly("num_non_finite", &R::num_non_finite)
      .def_readonly("ms_depth", &R::ms_depth)
      .def_readonly("ms_voxel", &R::ms_voxel)
      .def_readonly("ms_ground", &R::ms_ground)
      .def_readonly("ms_outlier", &R::ms_outlier)
      .def("__repr__", [](const R& r) {
        return "<PreprocessResult points=" + std::to_string(r.points.rows()) +
               " voxels=" + std::to_string(r.num_voxels) + ">";
      });
  const ds3d::PreprocessParams d;
  m.def("preprocess", &run, py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"),
        py::arg("cy"), py::arg("depth_scale") = 5000.0, py::arg("leaf_size") = d.voxel.leaf_size.dx,
        py::arg("stride") = d.depth.stride, py::arg("min_depth") = d.depth.min_depth,
        py::arg("max_depth") = d.depth.max_depth, py::arg("remove_ground") = d.remove_ground,
        py::arg("ground_threshold") = d.ground.distance_threshold,
        py::arg("ground_max_iterations") = d.ground.max_iterations,
        py::arg("ground_normal_prior") = std::optional<std::array<double, 3>>(std::array<double, 3>{
            d.ground.normal_prior.x(), d.ground.normal_prior.y(), d.ground.normal_prior.z()}),
        py::arg("ground_max_angle_deg") = d.ground.max_angle_deg,
        py::arg("remove_outliers") = d.remove_outliers,
        py::arg("outlier_radius") = d.outlier.radius,
        py::arg("outlier_min_neighbors") = d.outlier.min_neighbors,
        py::arg("num_threads") = d.num_threads,
        "Depth (H, W) uint16 -> voxel centroids -> ground removal -> radius outliers in one call\n"
        "(include/ds3d/preprocess.hpp). ground_normal_prior=None accepts any plane; otherwise\n"
        "the ground must be within ground_max_angle_deg of it and below the camera.");
  m.def("preprocess", &run_camera, py::arg("depth"), py::arg("camera"), py::kw_only(),
        py::arg("leaf_size") = d.voxel.leaf_size.dx, py::arg("stride") = d.depth.stride,
        py::arg("min_depth") = d.depth.min_depth, py::arg("max_depth") = d.depth.max_depth,
        py::arg("remove_ground") = d.remove_ground,
        py::arg("ground_threshold") = d.ground.distance_threshold,
        py::arg("ground_max_iterations") = d.ground.max_iterations,
        py::arg("ground_normal_prior") = std::optional<std::array<double, 3>>(std::array<double, 3>{
            d.ground.normal_prior.x(), d.ground.normal_prior.y(), d.ground.normal_prior.z()}),
        py::arg("ground_max_angle_deg") = d.ground.max_angle_deg,
        py::arg("remove_outliers") = d.remove_outliers,
        py::arg("outlier_radius") = d.outlier.radius,
        py::arg("outlier_min_neighbors") = d.outlier.min_neighbors,
        py::arg("num_threads") = d.num_threads,
        "preprocess(depth, camera, *, leaf_size=..., ...): the same with a ds3d.Camera, dict,\n"
        "preset name or camera.txt path of the image size (depth_scale from it; distortion is\n"
        "ignored, as in the fx fy cx cy form).");
}
