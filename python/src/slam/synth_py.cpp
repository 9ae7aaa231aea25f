// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/dataset.hpp and include/ds3d/synth.hpp (OpenCV parts). Images become
// numpy arrays (copies); cameras become dicts. The Python API is ds3d.synth (python/ds3d/synth.py).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "ds3d/errors.hpp"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/slam/synth.hpp"
#include "slam_py_util.hpp"

namespace py = pybind11;
using ds3d::py_slam::camera_dict;
using ds3d::py_slam::mat_to_array;

namespace {

py::dict frame_dict(const ds3d::synth::SynthFrame& f) {
  py::dict d;
  d["index"] = f.index;
  d["timestamp"] = f.timestamp;
  d["T_world_cam"] = py::array_t<double>({4, 4});
  Eigen::Matrix<double, 4, 4, Eigen::RowMajor> m = f.T_world_cam.matrix();
  std::memcpy(d["T_world_cam"].cast<py::array_t<double>>().mutable_data(), m.data(),
              sizeof(double) * 16);
  d["rgb"] = mat_to_array<std::uint8_t>(f.rgb);
  d["depth"] = mat_to_array<std::uint16_t>(f.depth);
  d["depth_true"] = mat_to_array<float>(f.depth_true);
  d["dynamic_mask"] = mat_to_array<std::uint8_t>(f.dynamic_mask);
  d["human_id"] = mat_to_array<std::uint8_t>(f.human_id);
  d["part_id"] = mat_to_array<std::uint8_t>(f.part_id);
  py::list boxes;
  for (const auto& b : f.boxes) {
    py::dict x;
    x["id"] = b.id;
    x["center"] = std::vector<double>{b.center.x(), b.center.y(), b.center.z()};
    x["size"] = std::vector<double>{b.size.x(), b.size.y(), b.size.z()};
    x["yaw"] = b.yaw;
    x["sitting"] = b.sitting;
    x["visible_pixels"] = b.visible_pixels;
    boxes.append(x);
  }
  d["boxes"] = boxes;
  return d;
}

ds3d::synth::SynthOptions make_options(const std::string& scenario, int frames, std::uint64_t seed,
                                       int humans, double fps, bool depth_noise, bool parts,
                                       const std::vector<double>& room, int furniture) {
  ds3d::synth::SynthOptions o;
  if (room.size() != 3) {
    throw ds3d::InvalidArgument("ds3d.synth: room_size must have 3 values (x, y, z) [m] (got " +
                                std::to_string(room.size()) + ")");
  }
  o.room_size = Eigen::Vector3d(room[0], room[1], room[2]);
  o.extra_furniture = furniture;
  o.scenario = ds3d::synth::parse_scenario(scenario);
  o.num_frames = frames;
  o.seed = seed;
  o.num_humans = humans;
  o.fps = fps;
  o.depth_noise = depth_noise;
  o.write_parts = parts;
  return o;
}

}  // namespace

void bind_synth(py::module_& m) {
  m.def(
      "camera_preset", [](const std::string& n) { return camera_dict(ds3d::camera_preset(n)); },
      py::arg("name"), "Intrinsics dict for 'tum1', 'tum2', 'tum3', 'tum_ros' or 'bonn'.");
  m.def(
      "read_camera_file",
      [](const std::string& p) { return camera_dict(ds3d::read_camera_file(p)); }, py::arg("path"),
      "camera.txt (fx fy cx cy k1 k2 p1 p2 k3 depth_scale) as a dict.");

  // ds3d.RgbdDataset is bound in dataset_py.cpp.

  py::class_<ds3d::synth::SyntheticScene>(m, "_SyntheticScene")
      .def(py::init([](const std::string& scenario, int frames, std::uint64_t seed, int humans,
                       double fps, bool depth_noise, const std::vector<double>& room,
                       int furniture) {
             return ds3d::synth::SyntheticScene(make_options(scenario, frames, seed, humans, fps,
                                                             depth_noise, false, room, furniture));
           }),
           py::arg("scenario"), py::arg("frames"), py::arg("seed"), py::arg("humans"),
           py::arg("fps"), py::arg("depth_noise"), py::arg("room_size"), py::arg("furniture"))
      .def("__len__", &ds3d::synth::SyntheticScene::size)
      .def("render", [](const ds3d::synth::SyntheticScene& s, std::size_t i) {
        ds3d::synth::SynthFrame f;
        {
          py::gil_scoped_release release;
          f = s.render(i);
        }
        return frame_dict(f);
      });
  m.def(
      "_synth_generate",
      [](const std::string& out_dir, const std::string& scenario, int frames, std::uint64_t seed,
         int humans, double fps, bool depth_noise, bool parts, const std::vector<double>& room,
         int furniture, bool overwrite) {
        const auto o =
            make_options(scenario, frames, seed, humans, fps, depth_noise, parts, room, furniture);
        ds3d::synth::SynthSummary s;
        {
          py::gil_scoped_release release;
          s = ds3d::synth::generate_sequence(out_dir, o, overwrite);
        }
        py::dict d;
        d["frames"] = s.frames;
        d["dynamic_pixels"] = s.dynamic_pixels;
        d["render_seconds"] = s.render_seconds;
        d["total_seconds"] = s.total_seconds;
        return d;
      },
      py::arg("out_dir"), py::arg("scenario"), py::arg("frames"), py::arg("seed"),
      py::arg("humans"), py::arg("fps"), py::arg("depth_noise"), py::arg("parts"),
      py::arg("room_size"), py::arg("furniture"), py::arg("overwrite") = false);
}
