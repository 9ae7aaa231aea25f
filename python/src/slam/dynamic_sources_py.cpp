// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/dynamic_sources.hpp: ds3d.DynamicObjects, the ds3d.DynamicObjectSource
// base (detect() on numpy images), ds3d.FileSource(+Params), ds3d.HdbscanMasker,
// ds3d._make_dynamic_source (every source of a SlamConfig; ds3d.make_dynamic_source wraps it),
// ds3d.image_boxes and ds3d.keypoint_array. GeometricMotionSource is in geometric_motion_py.cpp.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <memory>
#include <optional>
#include <string>

#include "../numpy_util.hpp"
#include "ds3d/slam/config.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "slam_py_util.hpp"

namespace py = pybind11;
namespace pu = ds3d::py_slam;
using ds3d::slam::DynamicObjects;
using ds3d::slam::DynamicObjectSource;
using ds3d::slam::EgoMotion;
using ds3d::slam::FileSource;
using ds3d::slam::FileSourceParams;
using ds3d::slam::HdbscanMasker;

namespace {

// (K, 4) float32 rows x_min y_min x_max y_max -> Rect2f list; NaN / inverted boxes rejected.
std::vector<cv::Rect2f> rects_from(const char* fn, const py::handle& obj) {
  const auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(obj);
  DS3D_CHECK(a && a.ndim() == 2 && a.shape(1) == 4, fn,
             ": boxes_2d must be a (K, 4) array [x_min y_min x_max y_max] (got ", pu::describe(obj),
             ")");
  std::vector<cv::Rect2f> out;
  const auto r = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    const float x0 = r(i, 0), y0 = r(i, 1), x1 = r(i, 2), y1 = r(i, 3);
    DS3D_CHECK(std::isfinite(x0) && std::isfinite(y0) && std::isfinite(x1) && std::isfinite(y1) &&
                   x1 >= x0 && y1 >= y0,
               fn, ": boxes_2d row ", i,
               " must be finite with x_max >= x_min and y_max >= y_min (got [", x0, ", ", y0, ", ",
               x1, ", ", y1, "])");
    out.emplace_back(x0, y0, x1 - x0, y1 - y0);
  }
  return out;
}

// (N, 3) float32 camera-frame points [m] (non-finite rows allowed: the masker ignores them).
ds3d::Points3f points_from(const char* fn, const char* name, const py::object& obj) {
  const auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(obj);
  DS3D_CHECK(a && a.ndim() == 2 && a.shape(1) == 3, fn, ": ", name,
             " must be an (N, 3) array of camera-frame points [m] (got ", pu::describe(obj), ")");
  ds3d::Points3f out(a.shape(0), 3);
  const auto r = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    for (int j = 0; j < 3; ++j) out(i, j) = r(i, j);
  }
  return out;
}

// A (4,) plane (a, b, c, d), finite with a non-zero normal; errors name `fn` and `name`.
Eigen::Vector4f plane_from(const char* fn, const char* name, const py::object& obj) {
  const auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(obj);
  DS3D_CHECK(a && a.ndim() == 1 && a.shape(0) == 4, fn, ": ", name,
             " must be a (4,) array (a, b, c, d) (got ", pu::describe(obj), ")");
  const Eigen::Vector4f q(a.at(0), a.at(1), a.at(2), a.at(3));
  DS3D_CHECK(q.allFinite() && q.head<3>().norm() > 0.0F, fn, ": ", name,
             " must be finite with a non-zero normal (got ", q.transpose(), ")");
  return q;
}

// ego_motion=(reference_timestamp, T_cur_ref): a finite time [s] and a (4, 4) rigid transform
// (orthonormal rotation with determinant 1 to 1e-6, last row 0 0 0 1, finite translation [m]).
EgoMotion ego_motion_from(const char* fn, const py::object& obj) {
  DS3D_CHECK(py::isinstance<py::tuple>(obj) && py::len(obj) == 2, fn,
             ": ego_motion must be a tuple (reference_timestamp, T_cur_ref) (got ",
             pu::describe(obj), ")");
  const auto t = py::cast<py::tuple>(obj);
  EgoMotion em;
  em.reference_timestamp = py::cast<double>(t[0]);
  DS3D_CHECK(std::isfinite(em.reference_timestamp), fn,
             ": ego_motion's reference_timestamp must be finite (got ", em.reference_timestamp,
             ")");
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(t[1]);
  DS3D_CHECK(a && a.ndim() == 2 && a.shape(0) == 4 && a.shape(1) == 4, fn,
             ": ego_motion's T_cur_ref must be a (4, 4) array (got ", pu::describe(t[1]), ")");
  Eigen::Matrix4d m;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) m(i, j) = a.at(i, j);
  }
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  const bool rigid = m.allFinite() && m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)) &&
                     (r.transpose() * r - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
                     std::abs(r.determinant() - 1.0) < 1e-6;
  DS3D_CHECK(rigid, fn, ": ego_motion's T_cur_ref must be a finite rigid transform (got\n", m, ")");
  em.T_cur_ref.matrix() = m;
  return em;
}

DynamicObjects objects_from(const py::object& boxes_2d, const py::object& scores,
                            const py::object& boxes_3d, const py::object& pixel_mask,
                            const py::object& boxes_3d_margin, const py::object& support_plane,
                            const py::object& foreground_points,
                            const py::object& boxes_3d_segmented, float foreground_radius,
                            const py::object& background_points, const py::object& segment_plane,
                            bool segment_outside_boxes, const py::object& ego_motion) {
  constexpr const char* fn = "ds3d.DynamicObjects";
  DynamicObjects o;
  if (!boxes_2d.is_none()) o.boxes_2d = rects_from(fn, boxes_2d);
  if (!scores.is_none()) {
    const auto s = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(scores);
    DS3D_CHECK(s && s.ndim() == 1 && static_cast<std::size_t>(s.shape(0)) == o.boxes_2d.size(), fn,
               ": scores must be a (K,) array, one per row of boxes_2d (got ", pu::describe(scores),
               " for ", o.boxes_2d.size(), " boxes)");
    for (py::ssize_t i = 0; i < s.shape(0); ++i) {
      const float v = s.at(i);
      DS3D_CHECK(v >= 0.0F && v <= 1.0F, fn, ": scores[", i, "] must be in [0, 1] (got ", v, ")");
      o.scores.push_back(v);
    }
  }
  if (!boxes_3d.is_none()) {
    const auto b = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(boxes_3d);
    DS3D_CHECK(b && b.ndim() == 3 && b.shape(1) == 8 && b.shape(2) == 3, fn,
               ": boxes_3d must be a (K, 8, 3) array of camera-frame corners [m] (got ",
               pu::describe(boxes_3d), ")");
    for (py::ssize_t k = 0; k < b.shape(0); ++k) {
      Eigen::Matrix<float, 8, 3> c;
      for (int i = 0; i < 8; ++i) {
        for (int j = 0; j < 3; ++j) {
          c(i, j) = b.at(k, i, j);
          DS3D_CHECK(std::isfinite(c(i, j)), fn, ": boxes_3d[", k, "] has a non-finite corner");
        }
      }
      o.boxes_3d.push_back(c);
    }
  }
  if (!boxes_3d_margin.is_none()) {
    const auto a =
        py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(boxes_3d_margin);
    DS3D_CHECK(a && a.ndim() == 1 && static_cast<std::size_t>(a.shape(0)) == o.boxes_3d.size(), fn,
               ": boxes_3d_margin must be a (K,) array, one per 3-D box (got ",
               pu::describe(boxes_3d_margin), " for ", o.boxes_3d.size(), " boxes)");
    for (py::ssize_t i = 0; i < a.shape(0); ++i) {
      const float v = a.at(i);
      DS3D_CHECK(v >= 0.0F, fn, ": boxes_3d_margin[", i, "] must be >= 0 or inf (got ", v, ")");
      o.boxes_3d_margin.push_back(v);
    }
  }
  if (!support_plane.is_none()) o.support_plane = plane_from(fn, "support_plane", support_plane);
  if (!foreground_points.is_none()) {
    o.segmentation.foreground_points = points_from(fn, "foreground_points", foreground_points);
  }
  if (!background_points.is_none()) {
    o.segmentation.background_points = points_from(fn, "background_points", background_points);
  }
  if (!boxes_3d_segmented.is_none()) {
    const auto a =
        py::array_t<bool, py::array::c_style | py::array::forcecast>::ensure(boxes_3d_segmented);
    DS3D_CHECK(a && a.ndim() == 1 && static_cast<std::size_t>(a.shape(0)) == o.boxes_3d.size(), fn,
               ": boxes_3d_segmented must be a (K,) bool array, one per 3-D box (got ",
               pu::describe(boxes_3d_segmented), " for ", o.boxes_3d.size(), " boxes)");
    for (py::ssize_t i = 0; i < a.shape(0); ++i) {
      o.segmentation.boxes_3d_segmented.push_back(a.at(i) ? 1 : 0);
    }
  }
  DS3D_CHECK(std::isfinite(foreground_radius) && foreground_radius > 0.0F, fn,
             ": foreground_radius must be finite and > 0 (got ", foreground_radius, ")");
  o.segmentation.foreground_radius = foreground_radius;
  if (!segment_plane.is_none())
    o.segmentation.segment_plane = plane_from(fn, "segment_plane", segment_plane);
  o.segmentation.segment_outside_boxes = segment_outside_boxes;
  if (!ego_motion.is_none()) o.ego_motion = ego_motion_from(fn, ego_motion);
  if (!pixel_mask.is_none()) {
    const auto m = pu::exact<std::uint8_t>(fn, "pixel_mask", pixel_mask, "an (H, W) uint8 array");
    DS3D_CHECK(m.ndim() == 2, fn, ": pixel_mask must be an (H, W) uint8 array (got ",
               pu::describe(pixel_mask), ")");
    cv::Mat(static_cast<int>(m.shape(0)), static_cast<int>(m.shape(1)), CV_8UC1,
            const_cast<std::uint8_t*>(m.data()))
        .copyTo(o.pixel_mask);
  }
  return o;
}

// Every per-frame call of the bindings takes (rgb, depth, camera, ...) in that order, as the C++
// detect(frame, camera) / mask(frame, camera, ...) do. A number or ORB features where the camera
// belongs is a call in another order: say which order, not only that the camera is malformed.
void check_camera_position(const char* fn, const char* signature, const py::object& camera) {
  const bool number = py::isinstance<py::float_>(camera) || py::isinstance<py::int_>(camera);
  if (number || py::isinstance<ds3d::slam::OrbFeatures>(camera)) {
    throw py::type_error(std::string(fn) + ": camera must be a ds3d.Camera, preset name, dict or "
                         "camera.txt path (got " + ds3d::py_camera::type_name(camera) +
                         "); the order is " + signature);
  }
}

// numpy images (viewed, not copied; the arrays are kept alive here) -> FrameInput, checked
// against the camera; errors name `fn`.
struct NumpyFrame {
  py::array_t<std::uint8_t, py::array::c_style> rgb_keep;
  py::array_t<std::uint16_t, py::array::c_style> depth_keep;
  ds3d::slam::FrameInput in;
  ds3d::PinholeCamera cam;

  NumpyFrame(const char* fn, const py::object& rgb, const py::object& depth, double timestamp,
             const py::object& camera, std::size_t index) {
    DS3D_CHECK(std::isfinite(timestamp), fn, ": timestamp must be finite (got ", timestamp, ")");
    in.index = index;
    in.timestamp = timestamp;
    in.rgb = pu::image_view(fn, rgb, rgb_keep);
    in.depth = pu::depth_view(fn, depth, depth_keep);
    cam = pu::camera_from(fn, camera);
    pu::check_size(fn, "rgb", in.rgb, cam);
    pu::check_size(fn, "depth", in.depth, cam);
  }
};

// Shared by every source: numpy images -> FrameInput -> detect() without the GIL.
DynamicObjects run_detect(DynamicObjectSource& src, const py::object& rgb, const py::object& depth,
                          const py::object& camera, double timestamp, std::size_t index) {
  const std::string name = "ds3d.DynamicObjectSource.detect (" + src.name() + ")";
  check_camera_position(name.c_str(), "detect(rgb, depth, camera, timestamp, index=0)", camera);
  NumpyFrame f(name.c_str(), rgb, depth, timestamp, camera, index);
  const py::gil_scoped_release release;
  // Sources may keep the frame's images as history (GeometricMotionSource copies the depth it
  // keeps, but the interface does not promise that of every source): give them owned copies,
  // not views of numpy memory that Python may free or overwrite before the next call.
  f.in.rgb = f.in.rgb.clone();
  f.in.depth = f.in.depth.clone();
  return src.detect(f.in, f.cam);
}

}  // namespace

void bind_dynamic_sources(py::module_& m) {
  py::class_<DynamicObjects>(
      m, "DynamicObjects",
      "What a dynamic-object source found in one frame (include/ds3d/slam_frontend.hpp).\n"
      "DynamicObjects(boxes_2d=None, scores=None, boxes_3d=None, pixel_mask=None,\n"
      "boxes_3d_margin=None, support_plane=None, foreground_points=None,\n"
      "boxes_3d_segmented=None, foreground_radius=0.2, background_points=None,\n"
      "segment_plane=None, segment_outside_boxes=False, ego_motion=None) builds one from\n"
      "your own detector's output (ValueError on bad shapes, non-finite values, inverted boxes).\n"
      "foreground_points (N, 3) [m, camera frame] and boxes_3d_segmented (K,) bool: a segmenting\n"
      "detector's points on its objects; the masker keeps the dynamic keypoints of a flagged box\n"
      "only within foreground_radius [m] of one and, when background_points (M, 3) (its points\n"
      "off the objects) are given, only where the nearest of all these points is a foreground\n"
      "one (ds3d.HdbscanMasker); segment_plane (4,): the plane the segmentation left out (its\n"
      "keypoints count as off the segment); segment_outside_boxes: the segmentation covers the\n"
      "whole frame and also marks keypoints outside the boxes. ego_motion\n"
      "(reference_timestamp, T_cur_ref): the camera's motion from the earlier frame with that\n"
      "timestamp [s] to this one, a (4, 4) rigid transform taking reference-camera points to\n"
      "this camera [m] (the geometric source reports it; the frontend.source_motion_gate key).")
      .def(py::init(&objects_from), py::arg("boxes_2d") = py::none(),
           py::arg("scores") = py::none(), py::arg("boxes_3d") = py::none(),
           py::arg("pixel_mask") = py::none(), py::arg("boxes_3d_margin") = py::none(),
           py::arg("support_plane") = py::none(), py::arg("foreground_points") = py::none(),
           py::arg("boxes_3d_segmented") = py::none(), py::arg("foreground_radius") = 0.2F,
           py::arg("background_points") = py::none(), py::arg("segment_plane") = py::none(),
           py::arg("segment_outside_boxes") = false, py::arg("ego_motion") = py::none())
      .def_property_readonly(
          "boxes_2d",
          [](const DynamicObjects& o) {
            py::array_t<float> a(
                {static_cast<py::ssize_t>(o.boxes_2d.size()), static_cast<py::ssize_t>(4)});
            auto r = a.mutable_unchecked<2>();
            for (std::size_t i = 0; i < o.boxes_2d.size(); ++i) {
              const auto& b = o.boxes_2d[i];
              const auto k = static_cast<py::ssize_t>(i);
              r(k, 0) = b.x;
              r(k, 1) = b.y;
              r(k, 2) = b.x + b.width;
              r(k, 3) = b.y + b.height;
            }
            return a;
          },
          "(K, 4) float32 image boxes [x_min y_min x_max y_max] [px, raw image].")
      .def_property_readonly(
          "scores", [](const DynamicObjects& o) { return ds3d::py_util::to_numpy(o.scores); },
          "(K,) float32 confidence per 2-D box in [0, 1], or empty.")
      .def_property_readonly(
          "boxes_3d",
          [](const DynamicObjects& o) {
            const auto k = static_cast<py::ssize_t>(o.boxes_3d.size());
            py::array_t<float> a({k, static_cast<py::ssize_t>(8), static_cast<py::ssize_t>(3)});
            auto r = a.mutable_unchecked<3>();
            for (py::ssize_t b = 0; b < k; ++b) {
              for (int i = 0; i < 8; ++i) {
                for (int j = 0; j < 3; ++j)
                  r(b, i, j) = o.boxes_3d[static_cast<std::size_t>(b)](i, j);
              }
            }
            return a;
          },
          "(K, 8, 3) float32 corners of 3-D boxes in the camera frame (x right, y down, z forward) "
          "[m].")
      .def_property_readonly(
          "boxes_3d_margin",
          [](const DynamicObjects& o) { return ds3d::py_util::to_numpy(o.boxes_3d_margin); },
          "(K,) float32 metric uncertainty [m] per 3-D box (inf: rectangle and depth range "
          "only), or empty.")
      .def_property_readonly(
          "support_plane",
          [](const DynamicObjects& o) -> py::object {
            if (!o.support_plane) return py::none();
            return py::cast(Eigen::Vector4f(*o.support_plane));
          },
          "(4,) floor plane (a, b, c, d) in the camera frame, or None.")
      .def_property_readonly(
          "foreground_points",
          [](const DynamicObjects& o) { return ds3d::Points3f(o.segmentation.foreground_points); },
          "(N, 3) float32 points segmented as on the objects [m, camera frame] (htx with "
          "segment), or (0, 3).")
      .def_property_readonly(
          "background_points",
          [](const DynamicObjects& o) { return ds3d::Points3f(o.segmentation.background_points); },
          "(M, 3) float32 points the same segmentation put off the objects [m, camera frame], "
          "or (0, 3).")
      .def_property_readonly(
          "boxes_3d_segmented",
          [](const DynamicObjects& o) {
            py::array_t<bool> a(static_cast<py::ssize_t>(o.segmentation.boxes_3d_segmented.size()));
            for (std::size_t i = 0; i < o.segmentation.boxes_3d_segmented.size(); ++i) {
              a.mutable_at(static_cast<py::ssize_t>(i)) =
                  o.segmentation.boxes_3d_segmented[i] != 0U;
            }
            return a;
          },
          "(K,) bool per 3-D box: its dynamic keypoints are confirmed against foreground_points; "
          "or empty.")
      .def_property_readonly(
          "segment_plane",
          [](const DynamicObjects& o) -> py::object {
            if (!o.segmentation.segment_plane) return py::none();
            return py::cast(Eigen::Vector4f(*o.segmentation.segment_plane));
          },
          "(4,) plane (a, b, c, d) in the camera frame that the segmentation's source left out of "
          "its input (htx: the floor), or None.")
      .def_property_readonly(
          "segment_outside_boxes",
          [](const DynamicObjects& o) { return o.segmentation.segment_outside_boxes; },
          "True when the segmentation also decides keypoints outside the boxes.")
      .def_property_readonly(
          "foreground_radius",
          [](const DynamicObjects& o) { return o.segmentation.foreground_radius; },
          "largest keypoint-to-foreground-point distance [m] for the segmentation check.")
      .def_property_readonly(
          "ego_motion",
          [](const DynamicObjects& o) -> py::object {
            if (!o.ego_motion) return py::none();
            return py::make_tuple(o.ego_motion->reference_timestamp,
                                  Eigen::Matrix4d(o.ego_motion->T_cur_ref.matrix()));
          },
          "(reference_timestamp [s], (4, 4) float64 T_cur_ref [m]): the camera's motion from "
          "that earlier frame to this one, as the source measured it, or None.")
      .def_property_readonly(
          "pixel_mask",
          [](const DynamicObjects& o) -> py::object {
            if (o.pixel_mask.empty()) return py::none();
            return pu::mat_to_array<std::uint8_t>(o.pixel_mask);
          },
          "(H, W) uint8 mask, non-zero = dynamic pixel, or None.")
      .def_property_readonly(
          "empty",
          [](const DynamicObjects& o) {
            return o.boxes_2d.empty() && o.boxes_3d.empty() &&
                   (o.pixel_mask.empty() || cv::countNonZero(o.pixel_mask) == 0);
          },
          "True when nothing was found (no box, no dynamic pixel).")
      .def("__repr__", [](const DynamicObjects& o) {
        return "DynamicObjects(" + std::to_string(o.boxes_2d.size()) + " 2-D boxes, " +
               std::to_string(o.boxes_3d.size()) +
               " 3-D boxes, pixel_mask=" + (o.pixel_mask.empty() ? "None" : "yes") + ")";
      });

  py::class_<DynamicObjectSource, std::shared_ptr<DynamicObjectSource>>(
      m, "DynamicObjectSource",
      "Base of the dynamic-object sources (file, geometric, htx, composites; "
      "include/ds3d/slam_frontend.hpp). Sources keep state across frames: call detect() in frame "
      "order on one sequence per instance.")
      .def("detect", &run_detect, py::arg("rgb"), py::arg("depth"), py::arg("camera"),
           py::arg("timestamp"), py::arg("index") = 0,
           "Objects in one frame. rgb: (H, W, 3) uint8 BGR or (H, W) uint8; depth: (H, W) uint16\n"
           "(camera depth_scale units per metre, 0 = missing) or None; camera: ds3d.Camera, preset\n"
           "name, dict or camera.txt path, of the image size; timestamp [s], finite,\n"
           "non-decreasing; index: position in the sequence (seeds the htx draw). Returns\n"
           "ds3d.DynamicObjects; releases the GIL. The source gets its own copy of the images (it\n"
           "may keep past frames), so the arrays may be reused afterwards. ValueError for a wrong\n"
           "dtype, shape or size; TypeError for a number or ORB features in the camera's place.")
      .def_property_readonly("name", &DynamicObjectSource::name,
                             "short name, e.g. 'file', 'htx+geometric'");

  py::class_<FileSourceParams>(m, "FileSourceParams", "Options of ds3d.FileSource.")
      .def(py::init<>())
      .def_readwrite("max_dt", &FileSourceParams::max_dt,
                     "largest frame <-> detection timestamp difference [s], >= 0")
      .def_readwrite("min_score", &FileSourceParams::min_score,
                     "detections below this score are dropped, in [0, 1]")
      .def_readwrite("classes", &FileSourceParams::classes,
                     "class names treated as dynamic (list of str); empty = every class")
      .def_readwrite("report_floor", &FileSourceParams::report_floor,
                     "report the frame's floor (RANSAC on its depth) as the support plane in "
                     "frames with boxes, so keypoints on it stay static (default True)")
      .def_readwrite("hold_frames", &FileSourceParams::hold_frames,
                     "frames a 3-D box is carried after the file last reported it, >= 0 (0 = off; "
                     "default 10): reported again, moved with the depth points in it, unless a "
                     "box of the frame continues it or fewer than hold_min_points remain")
      .def_readwrite("hold_min_points", &FileSourceParams::hold_min_points,
                     "depth points that keep a carried box, >= 1 (default 5)")
      .def_readwrite("hold_margin", &FileSourceParams::hold_margin,
                     "growth per side [m] of a carried box when its points are gathered, >= 0 "
                     "(default 0.15)")
      .def_readwrite("hold_seconds", &FileSourceParams::hold_seconds,
                     "longest time [s] a box is carried after the file reported it, >= 0 "
                     "(default 0.5)")
      .def("validate", &FileSourceParams::validate, "Raises ValueError naming the bad field.");

  py::class_<FileSource, DynamicObjectSource, std::shared_ptr<FileSource>>(
      m, "FileSource",
      "The 'file:PATH' source: boxes per timestamp from a JSON-lines detections file "
      "(include/ds3d/detections.hpp), so that any offline detector drives ds3d.")
      .def(py::init([](const py::object& path, const FileSourceParams& params) {
             return std::make_shared<FileSource>(std::filesystem::path(pu::path_from(path)),
                                                 params);
           }),
           py::arg("path"), py::arg("params") = FileSourceParams{},
           "Reads the file once. RuntimeError naming file and line for a malformed file; "
           "ValueError for bad params.")
      .def_static(
          "from_text",
          [](const std::string& text, const FileSourceParams& params) {
            return std::make_shared<FileSource>(ds3d::DetectionsFile::parse(text, "<text>"),
                                                params);
          },
          py::arg("text"), py::arg("params") = FileSourceParams{},
          "A source from the content of a detections file (one JSON object per line).")
      .def_property_readonly("num_matched", &FileSource::num_matched,
                             "frames so far whose timestamp matched a detections line")
      .def_property_readonly("num_unmatched", &FileSource::num_unmatched,
                             "frames so far with no detections line within max_dt")
      .def_property_readonly("num_carried", &FileSource::num_carried,
                             "held 3-D boxes reported so far, over all frames (hold_frames)");

  py::class_<HdbscanMasker, std::shared_ptr<HdbscanMasker>>(
      m, "HdbscanMasker",
      "The 'hdbscan' masker (3DS-SLAM §III-C): box-gated HDBSCAN on the ORB keypoints, boxes from\n"
      "DynamicObjects (2-D boxes, projected 3-D boxes) plus its pixel_mask. Keeps regions across\n"
      "frames: one instance per sequence, frames in order.")
      .def(py::init<const ds3d::DynamicFilterParams&>(),
           py::arg("params") = ds3d::DynamicFilterParams{})
      .def(
          "mask",
          [](HdbscanMasker& masker, const py::object& rgb, const py::object& depth,
             const py::object& camera, const ds3d::slam::OrbFeatures& features,
             const DynamicObjects& objects, double timestamp, std::size_t index) {
            constexpr const char* fn = "ds3d.HdbscanMasker.mask";
            check_camera_position(
                fn, "mask(rgb, depth, camera, features, objects, timestamp=0.0, index=0)", camera);
            const NumpyFrame f(fn, rgb, depth, timestamp, camera, index);
            if (!objects.pixel_mask.empty()) {
              pu::check_size(fn, "objects.pixel_mask", objects.pixel_mask, f.cam);
            }
            std::vector<std::uint8_t> out;
            {
              const py::gil_scoped_release release;
              out = masker.mask(f.in, f.cam, features, objects);
            }
            py::array_t<bool> a(static_cast<py::ssize_t>(out.size()));
            for (std::size_t i = 0; i < out.size(); ++i) a.mutable_data()[i] = out[i] != 0;
            return a;
          },
          py::arg("rgb"), py::arg("depth"), py::arg("camera"), py::arg("features"),
          py::arg("objects"), py::arg("timestamp") = 0.0, py::arg("index") = 0,
          "(N,) bool, True = keypoint i of `features` (ds3d.OrbExtractor.extract of this frame)\n"
          "lies on a moving object of `objects`. Images and camera as DynamicObjectSource.detect.")
      .def_property_readonly(
          "last_result", [](const HdbscanMasker& h) { return h.last_result(); },
          "ds3d.DynamicFilterResult of the last mask() call (dynamic, num_dynamic, ...).")
      .def_property_readonly("name", &HdbscanMasker::name);

  m.def(
      "keep_anchored_foreground",
      [](DynamicObjects objects, float margin) {
        const std::size_t moved = ds3d::slam::keep_anchored_foreground(objects, margin);
        return py::make_tuple(std::move(objects), moved);
      },
      py::arg("objects"), py::arg("margin"),
      "Keeps as foreground only the segmented points connected to a 3-D box of `objects` (inside\n"
      "a box grown by margin [m] >= 0 or inf, or within foreground_radius of such a point, and\n"
      "so on); the other finite foreground points move to the background points. Returns\n"
      "(new DynamicObjects, number moved); `objects` is not changed. ValueError on a bad margin\n"
      "or foreground_radius (HtxSource's segment_outside_boxes; docs/dynamic.md).");

  m.def(
      "_make_dynamic_source",
      [](const ds3d::slam::SlamConfig& c) {
        c.validate();
        return ds3d::slam::make_dynamic_source(c);
      },
      py::arg("config"), "Internal: see ds3d.make_dynamic_source (python/ds3d/slam.py).");

  m.def(
      "_make_masker",
      [](const ds3d::slam::SlamConfig& c, bool force) -> std::shared_ptr<HdbscanMasker> {
        // make_masker's rule (ds3d-slam): a masker from config.filter unless dynamic is "none".
        if (c.dynamic == "none" && !force) return nullptr;
        c.filter.validate();
        return std::make_shared<HdbscanMasker>(c.filter);
      },
      py::arg("config"), py::arg("force") = false,
      "Internal: the HdbscanMasker of a SlamConfig (None when dynamic.source is 'none', unless "
      "force); see ds3d.Slam.");

  m.def(
      "image_boxes",
      [](const DynamicObjects& objects, const py::object& camera) {
        return ds3d::slam::image_boxes(objects, pu::camera_from("ds3d.image_boxes", camera));
      },
      py::arg("objects"), py::arg("camera"),
      "list of ds3d.ImageBox: the 2-D boxes of `objects` (with scores) and its 3-D boxes\n"
      "projected with `camera` (with depth ranges); boxes wholly outside the image or behind the\n"
      "camera are left out.");

  m.def(
      "keypoint_array",
      [](const ds3d::slam::OrbFeatures& features, const py::object& depth,
         const py::object& camera) {
        constexpr const char* fn = "ds3d.keypoint_array";
        py::array_t<std::uint16_t, py::array::c_style> keep;
        const cv::Mat d = pu::depth_view(fn, depth, keep);
        const auto cam = pu::camera_from(fn, camera);
        pu::check_size(fn, "depth", d, cam);
        return ds3d::slam::keypoint_array(features, d, cam);
      },
      py::arg("features"), py::arg("depth"), py::arg("camera"),
      "(N, 3) float32 rows (u, v, z): raw keypoint pixel and the depth [m] of `depth` at the\n"
      "rounded pixel (0 = none) when depth is an (H, W) uint16 image of the camera size, else the\n"
      "features' own depth. The input of ds3d.DynamicFeatureFilter.filter.");
}
