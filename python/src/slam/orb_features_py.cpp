// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/orb_features.hpp: ds3d.OrbParams, ds3d.OrbExtractor and
// ds3d.OrbFeatures (arrays are numpy copies made on access).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <sstream>
#include <string>

#include "ds3d/slam/orb_features.hpp"
#include "slam_py_util.hpp"

namespace py = pybind11;
namespace pu = ds3d::py_slam;
using ds3d::slam::OrbExtractor;
using ds3d::slam::OrbFeatures;
using ds3d::slam::OrbParams;

namespace {

// (N,) array of one float member of each keypoint.
template <class T, class F>
py::array_t<T> per_keypoint(const OrbFeatures& f, F get) {
  py::array_t<T> a(static_cast<py::ssize_t>(f.size()));
  auto* p = a.mutable_data();
  for (std::size_t i = 0; i < f.size(); ++i) p[i] = static_cast<T>(get(i));
  return a;
}

py::array_t<float> xy_rows(std::size_t n, const auto& get) {
  py::array_t<float> a({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(2)});
  auto r = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < n; ++i) {
    const auto [x, y] = get(i);
    r(static_cast<py::ssize_t>(i), 0) = x;
    r(static_cast<py::ssize_t>(i), 1) = y;
  }
  return a;
}

}  // namespace

void bind_orb_features(py::module_& m) {
  py::class_<OrbParams>(m, "OrbParams",
                        "Parameters of ds3d.OrbExtractor (include/ds3d/orb_features.hpp); defaults "
                        "are ORB-SLAM2's for 640x480 RGB-D. validate() raises ValueError naming "
                        "the bad field; the extractor validates on construction.")
      .def(py::init<>())
      .def_readwrite("num_features", &OrbParams::num_features,
                     "target number of features over all levels, > 0")
      .def_readwrite("num_levels", &OrbParams::num_levels, "pyramid levels, in [1, 16]")
      .def_readwrite("scale_factor", &OrbParams::scale_factor,
                     "scale between consecutive levels, in (1, 2]")
      .def_readwrite("fast_threshold", &OrbParams::fast_threshold,
                     "FAST intensity threshold, in [1, 255]")
      .def_readwrite("min_fast_threshold", &OrbParams::min_fast_threshold,
                     "fallback threshold for grid cells with no corner, in [1, fast_threshold]")
      .def_readwrite("cell_size", &OrbParams::cell_size, "grid cell edge [px at that level], >= 8")
      .def_readwrite("max_depth", &OrbParams::max_depth,
                     "keypoints up to this depth [m] are 'close' (ORB-SLAM2's ThDepth), > 0")
      .def_readwrite("min_depth", &OrbParams::min_depth,
                     "depths below this [m] are treated as missing, >= 0")
      .def_readwrite("max_range", &OrbParams::max_range,
                     "depths beyond this [m] are treated as missing, >= max_depth")
      .def("validate", &OrbParams::validate, "Raises ValueError naming the bad field.")
      .def("__repr__", [](const OrbParams& p) {
        std::ostringstream s;
        s << "OrbParams(num_features=" << p.num_features << ", num_levels=" << p.num_levels
          << ", scale_factor=" << p.scale_factor << ", fast_threshold=" << p.fast_threshold
          << ", min_fast_threshold=" << p.min_fast_threshold << ", cell_size=" << p.cell_size
          << ", max_depth=" << p.max_depth << ", min_depth=" << p.min_depth
          << ", max_range=" << p.max_range << ")";
        return s.str();
      });

  py::class_<OrbFeatures>(m, "OrbFeatures",
                          "ORB features of one frame (ds3d.OrbExtractor.extract). Every array has "
                          "one row per keypoint, in the same order; each access returns a copy.")
      .def("__len__", &OrbFeatures::size)
      .def_property_readonly(
          "keypoints",
          [](const OrbFeatures& f) {
            return xy_rows(f.size(), [&](std::size_t i) {
              return std::pair{f.keypoints[i].pt.x, f.keypoints[i].pt.y};
            });
          },
          "(N, 2) float32 raw (distorted) pixel (u, v) at level 0 [px].")
      .def_property_readonly(
          "undistorted",
          [](const OrbFeatures& f) {
            return xy_rows(f.size(), [&](std::size_t i) {
              return std::pair{f.undistorted[i].x(), f.undistorted[i].y()};
            });
          },
          "(N, 2) float32 undistorted pixel (u, v) with the same intrinsics [px].")
      .def_property_readonly(
          "octave",
          [](const OrbFeatures& f) {
            return per_keypoint<std::int32_t>(f,
                                              [&](std::size_t i) { return f.keypoints[i].octave; });
          },
          "(N,) int32 pyramid level of each keypoint, in [0, num_levels).")
      .def_property_readonly(
          "angle",
          [](const OrbFeatures& f) {
            return per_keypoint<float>(f, [&](std::size_t i) { return f.keypoints[i].angle; });
          },
          "(N,) float32 orientation (intensity centroid) [deg], in [0, 360).")
      .def_property_readonly(
          "response",
          [](const OrbFeatures& f) {
            return per_keypoint<float>(f, [&](std::size_t i) { return f.keypoints[i].response; });
          },
          "(N,) float32 corner response (Harris score of the keypoint).")
      .def_property_readonly(
          "size",
          [](const OrbFeatures& f) {
            return per_keypoint<float>(f, [&](std::size_t i) { return f.keypoints[i].size; });
          },
          "(N,) float32 keypoint diameter at level 0 [px] (grows with the level's scale).")
      .def_property_readonly(
          "depth",
          [](const OrbFeatures& f) {
            return per_keypoint<float>(f, [&](std::size_t i) { return f.depth[i]; });
          },
          "(N,) float32 depth at the keypoint [m]; 0 = missing or outside [min_depth, max_range].")
      .def_property_readonly(
          "is_close",
          [](const OrbFeatures& f) {
            return per_keypoint<bool>(f, [&](std::size_t i) { return f.is_close(i); });
          },
          "(N,) bool: depth measured and <= close_depth (ORB-SLAM2's 'close' points).")
      .def_property_readonly(
          "descriptors",
          [](const OrbFeatures& f) {
            const auto n = static_cast<py::ssize_t>(f.size());
            py::array_t<std::uint8_t> a({n, static_cast<py::ssize_t>(32)});
            for (py::ssize_t i = 0; i < n; ++i) {
              std::memcpy(a.mutable_data(i, 0), f.descriptors.ptr(static_cast<int>(i)), 32);
            }
            return a;
          },
          "(N, 32) uint8 rotated-BRIEF descriptors (256 bits each).")
      .def_readonly("close_depth", &OrbFeatures::close_depth,
                    "the close/far depth threshold in use [m] (OrbParams.max_depth)")
      .def("__repr__", [](const OrbFeatures& f) {
        return "OrbFeatures(" + std::to_string(f.size()) + " keypoints)";
      });

  py::class_<OrbExtractor>(m, "OrbExtractor",
                           "Grid-bucketed multi-scale ORB extractor, ORB-SLAM2 style "
                           "(include/ds3d/orb_features.hpp). Deterministic; extract() releases "
                           "the GIL and may run concurrently from several threads.")
      .def(py::init<const OrbParams&>(), py::arg("params") = OrbParams{},
           "ValueError naming the bad field of params.")
      .def(
          "extract",
          [](const OrbExtractor& x, const py::object& rgb, const py::object& depth,
             const py::object& camera) {
            constexpr const char* fn = "ds3d.OrbExtractor.extract";
            py::array_t<std::uint8_t, py::array::c_style> rgb_keep;
            py::array_t<std::uint16_t, py::array::c_style> depth_keep;
            const cv::Mat image = pu::image_view(fn, rgb, rgb_keep);
            const cv::Mat d = pu::depth_view(fn, depth, depth_keep);
            const ds3d::PinholeCamera cam = pu::camera_from(fn, camera);
            pu::check_size(fn, "rgb", image, cam);
            pu::check_size(fn, "depth", d, cam);
            const py::gil_scoped_release release;
            return x.extract(image, d, cam);
          },
          py::arg("rgb"), py::arg("depth"), py::arg("camera"),
          "Features of one frame. rgb: (H, W, 3) uint8 BGR or (H, W) uint8 grey; depth: (H, W)\n"
          "uint16 (camera['depth_scale'] units per metre, 0 = missing) or None (every keypoint\n"
          "'far'); camera: dict (as ds3d.camera_preset), preset name or camera.txt path, of the\n"
          "image size. Returns ds3d.OrbFeatures. ValueError for a wrong dtype, shape or size.")
      .def("level_scale", &OrbExtractor::level_scale, py::arg("level"),
           "scale_factor**level: size of a level-`level` pixel in level-0 pixels.")
      .def_property_readonly(
          "params", [](const OrbExtractor& x) { return x.params(); },
          "the validated OrbParams (a copy)");
}
