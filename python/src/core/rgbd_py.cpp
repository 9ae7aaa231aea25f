// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/rgbd.hpp: ds3d.depth_to_points(depth, fx, fy, cx, cy,
// depth_scale=5000.0, stride=1, roi=None, min_depth=0.0, max_depth=inf, distortion=None).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <limits>
#include <optional>

#include "../camera_util.hpp"
#include "ds3d/preprocess/rgbd.hpp"
#include "numpy_util.hpp"

namespace py = pybind11;

namespace {

using RoiTuple = std::array<int, 4>;
using Distortion = std::array<double, 5>;

/// Camera + params from the Python keywords; width/height come from the image.
ds3d::PinholeCamera make_camera(Eigen::Index rows, Eigen::Index cols, double fx, double fy,
                                double cx, double cy, double depth_scale,
                                const std::optional<Distortion>& distortion) {
  ds3d::PinholeCamera cam;
  DS3D_CHECK(rows > 0 && cols > 0 && rows <= std::numeric_limits<int>::max() &&
                 cols <= std::numeric_limits<int>::max(),
             "ds3d.depth_to_points: depth must be a non-empty (H, W) image (got ", rows, "x", cols,
             ")");
  cam.width = static_cast<int>(cols);
  cam.height = static_cast<int>(rows);
  cam.fx = fx;
  cam.fy = fy;
  cam.cx = cx;
  cam.cy = cy;
  cam.depth_scale = depth_scale;
  if (distortion) {
    cam.k1 = (*distortion)[0];
    cam.k2 = (*distortion)[1];
    cam.p1 = (*distortion)[2];
    cam.p2 = (*distortion)[3];
    cam.k3 = (*distortion)[4];
  }
  return cam;
}

template <class Image>
ds3d::DepthToPointsResult run(const Eigen::Ref<const Image, 0, Eigen::OuterStride<>>& depth,
                              double fx, double fy, double cx, double cy, double depth_scale,
                              int stride, std::optional<RoiTuple> roi, double min_depth,
                              double max_depth, std::optional<Distortion> distortion,
                              bool undistort) {
  const ds3d::PinholeCamera cam =
      make_camera(depth.rows(), depth.cols(), fx, fy, cx, cy, depth_scale, distortion);
  ds3d::DepthToPointsParams p;
  p.stride = stride;
  if (roi) p.roi = {(*roi)[0], (*roi)[1], (*roi)[2], (*roi)[3]};
  p.min_depth = min_depth;
  p.max_depth = max_depth;
  p.undistort = undistort;
  const py::gil_scoped_release release;
  // Frame after frame of one distorted camera: the undistortion table is built once per thread.
  thread_local ds3d::PixelRayCache rays;
  if (undistort) p.rays = rays.get(cam);
  return ds3d::depth_to_points(depth, cam, p);
}

// The same with a camera (ds3d.Camera, dict, preset name or camera.txt path): intrinsics, depth
// scale and distortion from it; its size must be the image's.
template <class Image>
ds3d::DepthToPointsResult run_camera(const Eigen::Ref<const Image, 0, Eigen::OuterStride<>>& depth,
                                     const py::object& camera, int stride,
                                     std::optional<RoiTuple> roi, double min_depth,
                                     double max_depth, bool undistort) {
  constexpr const char* fn = "ds3d.depth_to_points";
  const auto c = ds3d::py_camera::camera_from(fn, camera);
  DS3D_CHECK(depth.rows() == c.height && depth.cols() == c.width, fn, ": depth is ", depth.rows(),
             "x", depth.cols(), " (H x W) but the camera is ", c.height, "x", c.width);
  return run<Image>(depth, c.fx, c.fy, c.cx, c.cy, c.depth_scale, stride, roi, min_depth, max_depth,
                    Distortion{c.k1, c.k2, c.p1, c.p2, c.k3}, undistort);
}

template <class Image>
void def_camera_overload(py::module_& m, bool noconvert) {
  m.def("depth_to_points", &run_camera<Image>, py::arg("depth").noconvert(noconvert),
        py::arg("camera"), py::kw_only(), py::arg("stride") = 1, py::arg("roi") = py::none(),
        py::arg("min_depth") = 0.0, py::arg("max_depth") = std::numeric_limits<double>::infinity(),
        py::arg("undistort") = true,
        "depth_to_points(depth, camera, *, stride=1, roi=None, min_depth=0, max_depth=inf,\n"
        "undistort=True): camera a ds3d.Camera, dict, preset name or camera.txt path of the\n"
        "image size (depth_scale and distortion from it).");
}

template <class Image>
void def_overload(py::module_& m, const char* doc) {
  m.def("depth_to_points", &run<Image>, py::arg("depth").noconvert(), py::arg("fx"), py::arg("fy"),
        py::arg("cx"), py::arg("cy"), py::arg("depth_scale") = 5000.0, py::arg("stride") = 1,
        py::arg("roi") = py::none(), py::arg("min_depth") = 0.0,
        py::arg("max_depth") = std::numeric_limits<double>::infinity(),
        py::arg("distortion") = py::none(), py::arg("undistort") = true, doc);
}

}  // namespace

void bind_rgbd(py::module_& m) {
  py::class_<ds3d::DepthToPointsResult>(m, "DepthToPointsResult",
                                        "Output of depth_to_points (include/ds3d/rgbd.hpp).")
      .def_readonly("points", &ds3d::DepthToPointsResult::points, "(N, 3) float32 [m]")
      .def_readonly("pixels", &ds3d::DepthToPointsResult::pixels, "(N, 2) int32 (u, v)")
      .def_readonly("num_invalid", &ds3d::DepthToPointsResult::num_invalid)
      .def_readonly("num_out_of_range", &ds3d::DepthToPointsResult::num_out_of_range)
      .def("__repr__", [](const ds3d::DepthToPointsResult& r) {
        return "<DepthToPointsResult points=" + std::to_string(r.points.rows()) + ">";
      });
  const char* doc =
      "Back-project a depth image (TUM convention, see include/ds3d/rgbd.hpp).\n"
      "depth: (H, W) uint16 in 1/depth_scale metres, or float32/float64 in metres; 0 and NaN\n"
      "are skipped. roi: (u0, v0, width, height), 0 = to the border. distortion: (k1, k2, p1,\n"
      "p2, k3). Returns .points (N, 3) and .pixels (N, 2: u, v) in row-major pixel order.";
  def_overload<ds3d::DepthImageU16>(m, doc);
  def_overload<ds3d::DepthImageF>(m, doc);
  // float64 (or other numeric) images: converted to float32 metres.
  m.def("depth_to_points", &run<ds3d::DepthImageF>, py::arg("depth"), py::arg("fx"), py::arg("fy"),
        py::arg("cx"), py::arg("cy"), py::arg("depth_scale") = 5000.0, py::arg("stride") = 1,
        py::arg("roi") = py::none(), py::arg("min_depth") = 0.0,
        py::arg("max_depth") = std::numeric_limits<double>::infinity(),
        py::arg("distortion") = py::none(), py::arg("undistort") = true, doc);
  def_camera_overload<ds3d::DepthImageU16>(m, true);
  def_camera_overload<ds3d::DepthImageF>(m, true);
  def_camera_overload<ds3d::DepthImageF>(m, false);
}
