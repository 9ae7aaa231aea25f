// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// One camera argument for every binding: a ds3d.Camera, a dict (keys of camera_dict()), a preset
// name (tum1 tum2 tum3 tum_ros bonn) or a camera.txt path, turned into a validated PinholeCamera.
#include <pybind11/pybind11.h>

#include <cmath>
#include <string>

#include "ds3d/camera.hpp"
#include "ds3d/errors.hpp"

namespace ds3d::py_camera {

namespace py = pybind11;

/// Resolves a preset name or a camera.txt path; set by the SLAM bindings (python/src/slam/
/// dataset_py.cpp), which hold the presets and the file reader. Null in a build without them.
inline PinholeCamera (*camera_from_spec)(const std::string& spec) = nullptr;

/// True for the five preset names.
inline bool is_preset(const std::string& s) {
  return s == "tum1" || s == "tum2" || s == "tum3" || s == "tum_ros" || s == "bonn";
}

/// The Python type name of `obj` (for error messages).
inline std::string type_name(const py::handle& obj) {
  return py::str(py::type::of(obj).attr("__name__")).cast<std::string>();
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

/// Sets the field `key` of `c` from a number; errors name `fn` and the key.
inline void set_field(const char* fn, PinholeCamera& c, const std::string& key,
                      const py::handle& value) {
  double v = 0;
  try {
    v = value.cast<double>();
  } catch (const py::cast_error&) {
    throw InvalidArgument(std::string(fn) + ": camera['" + key + "'] must be a number (got " +
                          type_name(value) + ")");
  }
  if (key == "width" || key == "height") {
    DS3D_CHECK(std::isfinite(v) && v == std::floor(v) && v > 0 && v < 1e6, fn, ": camera['", key,
               "'] must be a positive integer (got ", v, ")");
    (key == "width" ? c.width : c.height) = static_cast<int>(v);
    return;
  }
  double* const fields[] = {&c.fx, &c.fy, &c.cx, &c.cy, &c.k1,
                            &c.k2, &c.p1, &c.p2, &c.k3, &c.depth_scale};
  const char* const names[] = {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "depth_scale"};
  for (std::size_t i = 0; i < std::size(names); ++i) {
    if (key == names[i]) {
      *fields[i] = v;
      return;
    }
  }
  throw InvalidArgument(std::string(fn) + ": camera has an unknown key '" + key + "'");
}

/// A camera from a dict: fx fy cx cy required, the other keys default as in PinholeCamera.
inline PinholeCamera camera_from_dict(const char* fn, const py::dict& d) {
  PinholeCamera c;
  for (const auto& kv : d) set_field(fn, c, py::str(kv.first).cast<std::string>(), kv.second);
  for (const char* k : {"fx", "fy", "cx", "cy"}) {
    DS3D_CHECK(d.contains(k), fn, ": camera dict lacks '", k, "'");
  }
  return c;
}

/// The camera argument of `fn`: a ds3d.Camera, a dict, a preset name or a camera.txt path
/// (str or os.PathLike); validated. @throws InvalidArgument (ValueError) naming `fn`.
inline PinholeCamera camera_from(const char* fn, const py::handle& obj) {
  PinholeCamera c;
  if (py::isinstance<PinholeCamera>(obj)) {
    c = obj.cast<PinholeCamera>();
  } else if (py::isinstance<py::str>(obj) || py::hasattr(obj, "__fspath__")) {
    const auto s = py::str(py::module_::import("os").attr("fspath")(obj)).cast<std::string>();
    DS3D_CHECK(camera_from_spec != nullptr, fn, ": camera '", s,
               "' (a preset name or camera.txt path) needs the SLAM component of ds3d; pass a "
               "ds3d.Camera or a dict");
    c = camera_from_spec(s);
  } else {
    DS3D_CHECK(py::isinstance<py::dict>(obj), fn,
               ": camera must be a dict (fx fy cx cy [width height k1 k2 p1 p2 k3 depth_scale]), "
               "a ds3d.Camera, a preset name (tum1 tum2 tum3 tum_ros bonn) or a camera.txt path "
               "(got ",
               type_name(obj), ")");
    c = camera_from_dict(fn, py::reinterpret_borrow<py::dict>(obj));
  }
  c.validate(fn);
  return c;
}

}  // namespace ds3d::py_camera
