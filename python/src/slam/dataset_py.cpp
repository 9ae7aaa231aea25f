// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/dataset.hpp: ds3d.RgbdDataset (TUM / Bonn folders) as a Python
// sequence of frame dicts (numpy copies), with the camera as a dict and the groundtruth as an
// (n, 8) array. camera_preset / read_camera_file are bound in synth_py.cpp.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>

#include "ds3d/slam/dataset.hpp"
#include "slam_py_util.hpp"

namespace py = pybind11;
namespace pu = ds3d::py_slam;

namespace {

py::dict frame_dict(const ds3d::RgbdDataset& ds, std::size_t i) {
  ds3d::RgbdFrame f;
  {
    const py::gil_scoped_release release;
    f = ds.frame(i);
  }
  py::dict d;
  d["index"] = f.index;
  d["timestamp"] = f.timestamp;
  d["depth_timestamp"] = f.depth_timestamp;
  d["rgb"] = pu::mat_to_array<std::uint8_t>(f.rgb);
  d["depth"] = pu::mat_to_array<std::uint16_t>(f.depth);
  return d;
}

// Python index (negative counts from the end) -> position; IndexError outside, as a sequence must.
std::size_t wrap_index(const ds3d::RgbdDataset& ds, py::ssize_t i) {
  const auto n = static_cast<py::ssize_t>(ds.size());
  const py::ssize_t j = i < 0 ? i + n : i;
  if (j < 0 || j >= n) {
    throw py::index_error("ds3d.RgbdDataset: index " + std::to_string(i) + " out of range for " +
                          std::to_string(n) + " frames");
  }
  return static_cast<std::size_t>(j);
}

}  // namespace

void bind_dataset(py::module_& m) {
  // Preset names and camera.txt paths for every camera argument (camera_util.hpp).
  ds3d::py_camera::camera_from_spec = [](const std::string& spec) {
    return ds3d::py_camera::is_preset(spec) ? ds3d::camera_preset(spec)
                                            : ds3d::read_camera_file(spec);
  };
  py::class_<ds3d::RgbdDataset>(
      m, "RgbdDataset",
      "A TUM RGB-D / Bonn RGB-D Dynamic folder read frame by frame (include/ds3d/dataset.hpp).\n\n"
      "RgbdDataset(directory (str or path), max_difference=0.02, offset=0.0, camera=None): reads "
      "rgb.txt and\n"
      "depth.txt and associates them like the TUM associate.py (greedy, |t_rgb - (t_depth +\n"
      "offset)| < max_difference [s]); no image is read until a frame is asked for. camera\n"
      "overrides camera.txt / the default (tum_ros): a dict, a preset name or a camera.txt path.\n"
      "len(ds), ds[i] (negative i from the end) and iteration give frame dicts:\n"
      "index, timestamp [s], depth_timestamp [s], rgb (H, W, 3) uint8 BGR, depth (H, W) uint16\n"
      "(camera['depth_scale'] units per metre, 0 = missing). Raises RuntimeError for a missing\n"
      "folder or list or an unreadable image, ValueError for bad options.")
      .def(py::init([](const py::object& dir, double max_difference, double offset,
                       const py::object& camera) {
             ds3d::DatasetOptions opt{.max_difference = max_difference, .offset = offset};
             if (!camera.is_none()) opt.camera = pu::camera_from("ds3d.RgbdDataset", camera);
             return ds3d::RgbdDataset::open(pu::path_from(dir), opt);
           }),
           py::arg("directory"), py::arg("max_difference") = 0.02, py::arg("offset") = 0.0,
           py::arg("camera") = py::none())
      .def("__len__", &ds3d::RgbdDataset::size)
      .def(
          "__getitem__",
          [](const ds3d::RgbdDataset& ds, py::ssize_t i) {
            return frame_dict(ds, wrap_index(ds, i));
          },
          py::arg("i"), "Frame i as a dict (see the class doc); IndexError outside [-len, len).")
      .def(
          "frame", [](const ds3d::RgbdDataset& ds, std::size_t i) { return frame_dict(ds, i); },
          py::arg("i"),
          "Frame i in [0, len) as a dict: index, timestamp, depth_timestamp, rgb (H, W, 3 BGR "
          "uint8), depth (H, W uint16). ValueError for i >= len.")
      .def_property_readonly(
          "camera", [](const ds3d::RgbdDataset& ds) { return pu::camera_dict(ds.camera()); },
          "Intrinsics dict: fx fy cx cy width height k1 k2 p1 p2 k3 depth_scale.")
      .def_property_readonly(
          "directory", [](const ds3d::RgbdDataset& ds) { return ds.directory().string(); },
          "The folder given to the constructor.")
      .def_property_readonly(
          "groundtruth_path",
          [](const ds3d::RgbdDataset& ds) -> py::object {
            const auto p = ds.groundtruth_path();
            return p ? py::object(py::str(p->string())) : py::object(py::none());
          },
          "Path of groundtruth.txt in the folder, or None.")
      .def(
          "groundtruth",
          [](const ds3d::RgbdDataset& ds) -> py::object {
            const auto p = ds.groundtruth_path();
            if (!p) return py::none();
            return py::module_::import("ds3d._ds3d").attr("read_tum_trajectory")(p->string());
          },
          "groundtruth.txt as an (n, 8) float64 array [t tx ty tz qx qy qz qw] (camera-to-world,\n"
          "sorted; see read_tum_trajectory), or None when the folder has none.")
      .def_property_readonly(
          "timestamps",
          [](const ds3d::RgbdDataset& ds) {
            py::array_t<double> a(static_cast<py::ssize_t>(ds.size()));
            auto* p = a.mutable_data();
            for (const auto& e : ds.entries()) *p++ = e.timestamp;
            return a;
          },
          "(n,) float64 rgb timestamps [s] of the associated frames.")
      .def_property_readonly(
          "depth_timestamps",
          [](const ds3d::RgbdDataset& ds) {
            py::array_t<double> a(static_cast<py::ssize_t>(ds.size()));
            auto* p = a.mutable_data();
            for (const auto& e : ds.entries()) *p++ = e.depth_timestamp;
            return a;
          },
          "(n,) float64 associated depth timestamps [s].")
      .def_property_readonly(
          "rgb_files",
          [](const ds3d::RgbdDataset& ds) {
            std::vector<std::string> v;
            for (const auto& e : ds.entries()) v.push_back(e.rgb_file);
            return v;
          },
          "rgb file of each frame, relative to directory (as listed in rgb.txt).")
      .def_property_readonly(
          "depth_files",
          [](const ds3d::RgbdDataset& ds) {
            std::vector<std::string> v;
            for (const auto& e : ds.entries()) v.push_back(e.depth_file);
            return v;
          },
          "depth file of each frame, relative to directory (as listed in depth.txt).")
      .def("__repr__", [](const ds3d::RgbdDataset& ds) {
        return "RgbdDataset('" + ds.directory().string() + "', " + std::to_string(ds.size()) +
               " frames)";
      });
}
