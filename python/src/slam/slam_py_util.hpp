// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Helpers shared by the SLAM-side bindings (dataset, orb_features, dynamic_sources,
// geometric_motion): images numpy <-> cv::Mat with ValueErrors that name the function, the
// parameter and the offending dtype/shape; cameras come from camera_util.hpp.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "../camera_util.hpp"
#include "ds3d/camera.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/slam/dataset.hpp"

namespace ds3d::py_slam {

namespace py = pybind11;

/// "array of dtype D and shape (a, b)" or the Python type name, for error messages.
inline std::string describe(const py::handle& obj) {
  if (py::isinstance<py::array>(obj)) {
    const auto a = py::reinterpret_borrow<py::array>(obj);
    std::string s = "array of dtype " + py::str(a.dtype()).cast<std::string>() + " and shape (";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
    return s + (a.ndim() == 1 ? ",)" : ")");
  }
  return py::str(py::type::of(obj)).cast<std::string>();
}

/// A str or os.PathLike argument as a string (TypeError from os.fspath otherwise).
inline std::string path_from(const py::handle& obj) {
  return py::str(py::module_::import("os").attr("fspath")(obj)).cast<std::string>();
}

/// Copy of an 8-bit or 16-bit cv::Mat as an (H, W) or (H, W, C) numpy array.
template <class T>
py::array_t<T> mat_to_array(const cv::Mat& m) {
  std::vector<py::ssize_t> shape{m.rows, m.cols};
  if (m.channels() > 1) shape.push_back(m.channels());
  py::array_t<T> a(shape);
  const std::size_t row_bytes = static_cast<std::size_t>(m.cols) * m.elemSize();
  for (int y = 0; y < m.rows; ++y) {
    std::memcpy(reinterpret_cast<char*>(a.mutable_data()) + static_cast<std::size_t>(y) * row_bytes,
                m.ptr(y), row_bytes);
  }
  return a;
}

/// A C-contiguous array of exactly dtype T (no silent casts): `obj` must already have that dtype.
template <class T>
py::array_t<T, py::array::c_style> exact(const char* fn, const char* param, const py::handle& obj,
                                         const char* expected) {
  DS3D_CHECK(py::isinstance<py::array_t<T>>(obj), fn, ": ", param, " must be ", expected, " (got ",
             describe(obj), ")");
  return py::array_t<T, py::array::c_style>::ensure(obj);
}

/// The rgb argument: (H, W, 3) uint8 BGR or (H, W) uint8 grey, viewed (no copy) as a cv::Mat that
/// stays valid while `keep` lives.
inline cv::Mat image_view(const char* fn, const py::handle& obj,
                          py::array_t<std::uint8_t, py::array::c_style>& keep) {
  constexpr const char* kWant = "an (H, W, 3) uint8 BGR or (H, W) uint8 grey array";
  keep = exact<std::uint8_t>(fn, "rgb", obj, kWant);
  DS3D_CHECK((keep.ndim() == 3 && keep.shape(2) == 3) || keep.ndim() == 2, fn, ": rgb must be ",
             kWant, " (got ", describe(obj), ")");
  DS3D_CHECK(keep.shape(0) > 0 && keep.shape(1) > 0, fn, ": rgb must not be empty (got ",
             describe(obj), ")");
  return {static_cast<int>(keep.shape(0)), static_cast<int>(keep.shape(1)),
          keep.ndim() == 3 ? CV_8UC3 : CV_8UC1, const_cast<std::uint8_t*>(keep.data())};
}

/// The depth argument: (H, W) uint16 (camera depth_scale units per metre, 0 = none) or None
/// (empty cv::Mat), viewed without a copy while `keep` lives.
inline cv::Mat depth_view(const char* fn, const py::handle& obj,
                          py::array_t<std::uint16_t, py::array::c_style>& keep) {
  if (obj.is_none()) return {};
  constexpr const char* kWant = "an (H, W) uint16 array or None";
  keep = exact<std::uint16_t>(fn, "depth", obj, kWant);
  DS3D_CHECK(keep.ndim() == 2, fn, ": depth must be ", kWant, " (got ", describe(obj), ")");
  return {static_cast<int>(keep.shape(0)), static_cast<int>(keep.shape(1)), CV_16UC1,
          const_cast<std::uint16_t*>(keep.data())};
}

/// Cameras: see python/src/camera_util.hpp (a ds3d.Camera, a dict, a preset name or a path).
using py_camera::camera_dict;
using py_camera::camera_from;

/// Checks that an image of h × w pixels matches the camera size.
inline void check_size(const char* fn, const char* param, const cv::Mat& m,
                       const PinholeCamera& c) {
  if (m.empty()) return;
  DS3D_CHECK(m.cols == c.width && m.rows == c.height, fn, ": ", param, " is ", m.rows, "x", m.cols,
             " (H x W) but the camera is ", c.height, "x", c.width);
}

}  // namespace ds3d::py_slam
