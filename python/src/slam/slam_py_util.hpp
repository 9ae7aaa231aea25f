// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Helpers shared by the SLAM-side bindings (dataset, orb_features, dynamic_sources,
// geometric_motion): images numpy <-> cv::Mat with ValueErrors that name the function, the
// parameter and the offending dtype/shape, and cameras as dicts (the convention of
// ds3d.camera_preset and RgbdDataset.camera).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/errors.hpp"

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

/// Camera as a dict: fx fy cx cy width height k1 k2 p1 p2 k3 depth_scale.
inline py::dict camera_dict(const PinholeCamera& c) {
  py::dict d;
  d["fx"] = c.fx;
  d["fy"] = c.fy;
  d["cx"] = c.cx;
  d["cy"] = c.cy;
  d["width"] = c.width;
  d["height"] = c.height;
  d["k1"] = c.k1;
  d["k2"] = c.k2;
  d["p1"] = c.p1;
  d["p2"] = c.p2;
  d["k3"] = c.k3;
  d["depth_scale"] = c.depth_scale;
  return d;
}

/// A camera from a dict (keys of camera_dict(); fx fy cx cy required, others default as in
/// PinholeCamera), a preset name (tum1 tum2 tum3 tum_ros bonn) or a camera.txt path; validated.
inline PinholeCamera camera_from(const char* fn, const py::handle& obj) {
  PinholeCamera c;
  if (py::isinstance<py::str>(obj) || py::hasattr(obj, "__fspath__")) {
    const auto s = path_from(obj);
    if (s == "tum1" || s == "tum2" || s == "tum3" || s == "tum_ros" || s == "bonn") {
      c = camera_preset(s);
    } else {
      c = read_camera_file(s);
    }
  } else {
    DS3D_CHECK(py::isinstance<py::dict>(obj), fn,
               ": camera must be a dict (fx fy cx cy [width height k1 k2 p1 p2 k3 depth_scale]), "
               "a preset name or a camera.txt path (got ",
               describe(obj), ")");
    const auto d = py::reinterpret_borrow<py::dict>(obj);
    for (const auto& kv : d) {
      const auto key = py::str(kv.first).cast<std::string>();
      const auto num = [&]() {
        try {
          return kv.second.cast<double>();
        } catch (const py::cast_error&) {
          throw InvalidArgument(std::string(fn) + ": camera['" + key + "'] must be a number (got " +
                                describe(kv.second) + ")");
        }
      };
      if (key == "fx") c.fx = num();
      else if (key == "fy") c.fy = num();
      else if (key == "cx") c.cx = num();
      else if (key == "cy") c.cy = num();
      else if (key == "k1") c.k1 = num();
      else if (key == "k2") c.k2 = num();
      else if (key == "p1") c.p1 = num();
      else if (key == "p2") c.p2 = num();
      else if (key == "k3") c.k3 = num();
      else if (key == "depth_scale") c.depth_scale = num();
      else if (key == "width" || key == "height") {
        const double v = num();
        DS3D_CHECK(std::isfinite(v) && v == std::floor(v) && v > 0 && v < 1e6, fn, ": camera['",
                   key, "'] must be a positive integer (got ", v, ")");
        (key == "width" ? c.width : c.height) = static_cast<int>(v);
      } else {
        throw InvalidArgument(std::string(fn) + ": camera has an unknown key '" + key + "'");
      }
    }
    for (const char* k : {"fx", "fy", "cx", "cy"}) {
      DS3D_CHECK(d.contains(k), fn, ": camera dict lacks '", k, "'");
    }
  }
  c.validate(fn);
  return c;
}

/// Checks that an image of h × w pixels matches the camera size.
inline void check_size(const char* fn, const char* param, const cv::Mat& m, const PinholeCamera& c) {
  if (m.empty()) return;
  DS3D_CHECK(m.cols == c.width && m.rows == c.height, fn, ": ", param, " is ", m.rows, "x", m.cols,
             " (H x W) but the camera is ", c.height, "x", c.width);
}

}  // namespace ds3d::py_slam
