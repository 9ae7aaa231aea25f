// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Binding for include/ds3d/camera.hpp: ds3d.Camera (PinholeCamera), the one camera type that
// every camera argument accepts (with dicts, preset names and camera.txt paths; camera_util.hpp).
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

#include "../camera_util.hpp"
#include "ds3d/camera.hpp"

namespace py = pybind11;
namespace pc = ds3d::py_camera;
using ds3d::PinholeCamera;

namespace {

PinholeCamera make(double fx, double fy, double cx, double cy, int width, int height,
                   double depth_scale, double k1, double k2, double p1, double p2, double k3) {
  PinholeCamera c{.fx = fx,
                  .fy = fy,
                  .cx = cx,
                  .cy = cy,
                  .width = width,
                  .height = height,
                  .k1 = k1,
                  .k2 = k2,
                  .p1 = p1,
                  .p2 = p2,
                  .k3 = k3,
                  .depth_scale = depth_scale};
  c.validate("ds3d.Camera");
  return c;
}

std::string repr(const PinholeCamera& c) {
  std::string s = "Camera(fx=" + py::repr(py::float_(c.fx)).cast<std::string>() +
                  ", fy=" + py::repr(py::float_(c.fy)).cast<std::string>() +
                  ", cx=" + py::repr(py::float_(c.cx)).cast<std::string>() +
                  ", cy=" + py::repr(py::float_(c.cy)).cast<std::string>() +
                  ", width=" + std::to_string(c.width) + ", height=" + std::to_string(c.height) +
                  ", depth_scale=" + py::repr(py::float_(c.depth_scale)).cast<std::string>();
  if (c.has_distortion()) {
    for (const auto& [name, v] :
         {std::pair{"k1", c.k1}, {"k2", c.k2}, {"p1", c.p1}, {"p2", c.p2}, {"k3", c.k3}}) {
      s += std::string(", ") + name + "=" + py::repr(py::float_(v)).cast<std::string>();
    }
  }
  return s + ")";
}

}  // namespace

void bind_camera(py::module_& m) {
  py::class_<PinholeCamera>(
      m, "Camera",
      "Pinhole RGB-D camera with OpenCV's k1 k2 p1 p2 k3 distortion (include/ds3d/camera.hpp).\n"
      "Camera(fx, fy, cx, cy, width=640, height=480, depth_scale=5000.0, k1=0, k2=0, p1=0, p2=0,\n"
      "k3=0): focal lengths and principal point [px], image size [px], depth-image units per\n"
      "metre. Camera(spec): spec a preset name (tum1 tum2 tum3 tum_ros bonn), a camera.txt path,\n"
      "a dict with keys fx fy cx cy [width height k1 k2 p1 p2 k3 depth_scale] or a Camera.\n"
      "Every function that takes a camera accepts a Camera or any such spec. Reads like a dict\n"
      "too: cam['fx'], dict(cam). ValueError naming the field for a bad value.")
      .def(py::init(&make), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
           py::arg("width") = 640, py::arg("height") = 480, py::arg("depth_scale") = 5000.0,
           py::arg("k1") = 0.0, py::arg("k2") = 0.0, py::arg("p1") = 0.0, py::arg("p2") = 0.0,
           py::arg("k3") = 0.0)
      .def(py::init([](const py::object& spec) { return pc::camera_from("ds3d.Camera", spec); }),
           py::arg("spec"))
      .def_static(
          "preset",
          [](const std::string& name) {
            DS3D_CHECK(pc::is_preset(name),
                       "ds3d.Camera.preset: name must be one of tum1 tum2 "
                       "tum3 tum_ros bonn (got '",
                       name, "')");
            return pc::camera_from("ds3d.Camera.preset", py::str(name));
          },
          py::arg("name"), "The intrinsics of 'tum1', 'tum2', 'tum3', 'tum_ros' or 'bonn'.")
      .def_readwrite("fx", &PinholeCamera::fx, "focal length along u [px], > 0")
      .def_readwrite("fy", &PinholeCamera::fy, "focal length along v [px], > 0")
      .def_readwrite("cx", &PinholeCamera::cx, "principal point u [px]")
      .def_readwrite("cy", &PinholeCamera::cy, "principal point v [px]")
      .def_readwrite("width", &PinholeCamera::width, "image width [px], > 0")
      .def_readwrite("height", &PinholeCamera::height, "image height [px], > 0")
      .def_readwrite("k1", &PinholeCamera::k1, "radial distortion (r^2)")
      .def_readwrite("k2", &PinholeCamera::k2, "radial distortion (r^4)")
      .def_readwrite("p1", &PinholeCamera::p1, "tangential distortion")
      .def_readwrite("p2", &PinholeCamera::p2, "tangential distortion")
      .def_readwrite("k3", &PinholeCamera::k3, "radial distortion (r^6)")
      .def_readwrite("depth_scale", &PinholeCamera::depth_scale, "depth-image units per metre, > 0")
      .def(
          "validate", [](const PinholeCamera& c) { c.validate("ds3d.Camera"); },
          "Raises ValueError naming the bad field.")
      .def("to_dict", &pc::camera_dict,
           "The camera as a dict: fx fy cx cy width height k1 k2 p1 p2 k3 depth_scale.")
      .def(
          "keys", [](const PinholeCamera& c) { return pc::camera_dict(c).attr("keys")(); },
          "The field names, as to_dict().keys().")
      .def(
          "__getitem__",
          [](const PinholeCamera& c, const std::string& key) -> py::object {
            const py::dict d = pc::camera_dict(c);
            if (!d.contains(key)) throw py::key_error(key);
            return d[py::str(key)];
          },
          py::arg("key"))
      .def(
          "__eq__",
          [](const PinholeCamera& a, const PinholeCamera& b) {
            return a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy &&
                   a.width == b.width && a.height == b.height && a.k1 == b.k1 && a.k2 == b.k2 &&
                   a.p1 == b.p1 && a.p2 == b.p2 && a.k3 == b.k3 && a.depth_scale == b.depth_scale;
          },
          py::is_operator())
      .def("__repr__", &repr)
      .def(py::pickle([](const PinholeCamera& c) { return pc::camera_dict(c); },
                      [](const py::dict& d) { return pc::camera_from_dict("ds3d.Camera", d); }));
}
