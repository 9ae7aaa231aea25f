// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/geometric_motion.hpp: ds3d.GeometricMotionParams,
// ds3d.GeometricMotionStats and ds3d.GeometricMotionSource (a ds3d.DynamicObjectSource: detect()
// comes from the base, dynamic_sources_py.cpp), with its diagnostics as numpy arrays.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <sstream>
#include <string>

#include "ds3d/slam/dynamic/geometric_motion.hpp"
#include "slam_py_util.hpp"

namespace py = pybind11;
using ds3d::slam::GeometricMotionParams;
using ds3d::slam::GeometricMotionSource;
using ds3d::slam::GeometricMotionStats;

// Every field of GeometricMotionParams with its Python docstring (units, range): one list drives
// the properties and __repr__, so that a new field needs one line here.
#define DS3D_GEOMETRIC_PARAMS(X)                                                                  \
  X(num_features, "ORB features of the source's own extractor, > 0")                              \
  X(reference_gap, "frames between the current and the reference frame, >= 1")                    \
  X(max_match_distance, "Hamming distance of accepted matches, in [1, 256]")                      \
  X(match_ratio, "best / second-best Hamming distance below this (Lowe's ratio), in (0, 1]")      \
  X(ransac_iterations, "PnP-RANSAC iterations, >= 1")                                             \
  X(chi2_2dof, "chi2 (2 dof, 95 %) of the pose inlier test, > 0")                                 \
  X(moving_chi2, "chi2 (3 dof, 99.9 %): a keypoint moves above this, > 0")                        \
  X(min_pixel_sigma, "floor of the per-frame pixel noise sigma_px [px], > 0")                     \
  X(depth_noise, "sigma(z) = depth_noise * z^2 [1/m], >= 0")                                      \
  X(min_depth_residual,                                                                           \
    "depth residuals below this never flag (sigma(z) floor = this / 3) [m], > 0")                 \
  X(depth_window, "half-size of the depth-spread window at keypoints [px], >= 0")                 \
  X(min_inlier_ratio, "trusted pose: inliers / matches at least this, in [0, 1]")                 \
  X(min_pose_inliers, "trusted pose: at least this many inliers, >= 6")                           \
  X(max_acceleration,                                                                             \
    "motion prior of the source's own pose [m/s^2], >= 0 (0 = off): a pose farther than this * "  \
    "dt^2 from the constant-velocity prediction may be replaced by one the prediction explains")  \
  X(hold_prediction_inliers,                                                                      \
    "a pose that breaks the motion prior with fewer inliers than this and no second hypothesis "  \
    "is replaced by the prediction itself, >= 0 (0 = off)")                                       \
  X(warp_gap, "frames between the current frame and the reference of the dense warp, >= 1")       \
  X(warp_stride, "grid step of the dense depth warp [px], >= 1")                                  \
  X(warp_window, "half-size of the depth-edge / min-depth window of the warp [px], >= 0")         \
  X(warp_chi2, "chi2 (1 dof, 99.9 %) of the warp's depth test, > 0")                              \
  X(min_warp_area, "smallest warp candidate (metric area of its pixels) [m^2], > 0")              \
  X(max_speed,                                                                                    \
    "fastest object motion the warp explains as a receding surface [m/s], >= 0 (0 = off)")        \
  X(image_scale, "the source's ORB runs on the image resized by this factor, in (0, 1]")          \
  X(max_depth, "depths beyond this are ignored [m], > 0")                                         \
  X(min_cluster_size, "HDBSCAN min_cluster_size (moving keypoints), >= 2")                        \
  X(min_samples, "HDBSCAN min_samples, >= 1")                                                     \
  X(min_support, "moving / tested keypoints in a cluster's region, in (0, 1]")                    \
  X(min_band_support,                                                                             \
    "support test of warp components (share of the tested cells within one cell that moved), in " \
    "[0, 1]; 0 (default) = none")                                                                 \
  X(max_object_size, "clusters larger than this in x, y or z are not objects [m], > 0")           \
  X(max_object_width, "widest object segment along the floor [m], > 0")                           \
  X(box_margin, "object boxes grow by this in x, y and z [m], >= 0")                              \
  X(hold_frames, "frames an object is kept after its last motion evidence, >= 0")                 \
  X(trust_first_candidates,                                                                       \
    "candidates of the first frame tested with a trusted pose become objects without a repeat "   \
    "(default True)")                                                                             \
  X(segment_objects,                                                                              \
    "grow each object over the depth-continuous surface around its evidence and report it as "    \
    "DynamicObjects.pixel_mask (False: boxes only)")

// Every field of GeometricMotionStats except the pose (bound separately as a 4x4 array).
#define DS3D_GEOMETRIC_STATS(X)                                                    \
  X(pose_ok, "a reference was available and the pose is trusted")                  \
  X(shared_orb, "the features came from the front-end's ORB corners")              \
  X(num_matches, "descriptor matches with the reference (reference depth)")        \
  X(num_pose_inliers, "PnP-RANSAC inliers")                                        \
  X(prior_replaced, "the motion prior replaced the largest-consensus pose")        \
  X(prediction_held, "the pose is the motion prior's prediction")                  \
  X(num_tested, "keypoints with depth in both views that were chi2-tested")        \
  X(num_moving_keypoints, "tested keypoints above moving_chi2")                    \
  X(num_warp_tested, "grid pixels tested by the dense depth warp")                 \
  X(num_moving_pixels, "grid pixels flagged by the dense depth warp")              \
  X(num_warp_candidates, "candidates found by the warp alone (before merging)")    \
  X(num_candidates, "clusters that passed the size and support tests")             \
  X(num_new_objects, "candidates confirmed this frame")                            \
  X(num_objects, "objects reported (new + held)")                                  \
  X(num_segments, "grown object segments in the pixel mask")                       \
  X(num_segments_leaked, "regions that outgrew the object size (seeds kept only)") \
  X(num_segment_cells, "warp grid cells in the pixel mask")                        \
  X(ground_found, "a floor plane bounded the segments")                            \
  X(pixel_sigma, "sigma_px used this frame [px]")

namespace {

py::array_t<double> matrix4(const Eigen::Isometry3d& T) {
  py::array_t<double> out({4, 4});
  auto a = out.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) a(r, c) = T.matrix()(r, c);
  }
  return out;
}

// Structured (N,) array: u v z chi2 (float32), moving (bool), cluster (int32), candidate (bool).
py::array tested_array(const std::vector<ds3d::slam::TestedKeypoint>& t) {
  const py::module_ np = py::module_::import("numpy");
  py::list fields;
  for (const char* f : {"u", "v", "z", "chi2"}) fields.append(py::make_tuple(f, "<f4"));
  fields.append(py::make_tuple("moving", "?"));
  fields.append(py::make_tuple("cluster", "<i4"));
  fields.append(py::make_tuple("candidate", "?"));
  py::object out = np.attr("zeros")(t.size(), np.attr("dtype")(fields));
  const auto column = [&](const char* name, auto get) {
    using T = decltype(get(t.front()));
    py::array_t<T> c(static_cast<py::ssize_t>(t.size()));
    for (std::size_t i = 0; i < t.size(); ++i) c.mutable_data()[i] = get(t[i]);
    out[py::str(name)] = c;
  };
  if (!t.empty()) {
    column("u", [](const auto& k) { return k.u; });
    column("v", [](const auto& k) { return k.v; });
    column("z", [](const auto& k) { return k.z; });
    column("chi2", [](const auto& k) { return k.chi2; });
    column("moving", [](const auto& k) { return k.moving; });
    column("cluster", [](const auto& k) { return static_cast<std::int32_t>(k.cluster); });
    column("candidate", [](const auto& k) { return k.candidate; });
  }
  return out;
}

// (M, 2) float32 array of pixel positions (u, v).
py::array_t<float> pixels_array(const std::vector<Eigen::Vector2f>& px) {
  py::array_t<float> a({static_cast<py::ssize_t>(px.size()), static_cast<py::ssize_t>(2)});
  auto r = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < px.size(); ++i) {
    r(static_cast<py::ssize_t>(i), 0) = px[i].x();
    r(static_cast<py::ssize_t>(i), 1) = px[i].y();
  }
  return a;
}

}  // namespace

void bind_geometric_motion(py::module_& m) {
  py::class_<GeometricMotionParams> params(
      m, "GeometricMotionParams",
      "Parameters of ds3d.GeometricMotionSource (include/ds3d/geometric_motion.hpp). Thresholds\n"
      "are statistical (chi2, sigma(z)) or metric; none is tuned to a recorded sequence.\n"
      "validate() raises ValueError naming the bad field; the source validates on construction.");
  params.def(py::init<>());
#define DS3D_BIND_FIELD(name, doc) params.def_readwrite(#name, &GeometricMotionParams::name, doc);
  DS3D_GEOMETRIC_PARAMS(DS3D_BIND_FIELD)
#undef DS3D_BIND_FIELD
  params
      .def("validate", &GeometricMotionParams::validate, "Raises ValueError naming the bad field.")
      .def("__repr__", [](const GeometricMotionParams& p) {
        std::ostringstream s;
        s << std::boolalpha << "GeometricMotionParams(";
        const char* sep = "";
#define DS3D_REPR_FIELD(name, doc) \
  s << sep << #name "=" << p.name; \
  sep = ", ";
        DS3D_GEOMETRIC_PARAMS(DS3D_REPR_FIELD)
#undef DS3D_REPR_FIELD
        s << ")";
        return s.str();
      });

  py::class_<GeometricMotionStats> stats(
      m, "GeometricMotionStats", "Counters of the last GeometricMotionSource.detect() call.");
#define DS3D_BIND_STAT(name, doc) stats.def_readonly(#name, &GeometricMotionStats::name, doc);
  DS3D_GEOMETRIC_STATS(DS3D_BIND_STAT)
#undef DS3D_BIND_STAT
  stats
      .def_property_readonly(
          "T_world_cam", [](const GeometricMotionStats& s) { return matrix4(s.T_world_cam); },
          "(4, 4) float64 the source's own camera-to-world pose (chained PnP poses).")
      .def(
          "as_dict",
          [](const GeometricMotionStats& s) {
            py::dict d;
#define DS3D_DICT_STAT(name, doc) d[#name] = s.name;
            DS3D_GEOMETRIC_STATS(DS3D_DICT_STAT)
#undef DS3D_DICT_STAT
            return d;
          },
          "The counters as a dict (one row of a pandas.DataFrame per frame).")
      .def("__repr__", [](const GeometricMotionStats& s) {
        std::ostringstream o;
        o << std::boolalpha << "GeometricMotionStats(";
        const char* sep = "";
#define DS3D_REPR_STAT(name, doc)  \
  o << sep << #name "=" << s.name; \
  sep = ", ";
        DS3D_GEOMETRIC_STATS(DS3D_REPR_STAT)
#undef DS3D_REPR_STAT
        o << ")";
        return o.str();
      });

  py::class_<GeometricMotionSource, ds3d::slam::DynamicObjectSource,
             std::shared_ptr<GeometricMotionSource>>(
      m, "GeometricMotionSource",
      "The 'geometric' dynamic-object source: moving objects from multi-view geometry alone, no\n"
      "learned weights (ORB matches + PnP-RANSAC pose, chi2 test of each keypoint's 3-D residual,\n"
      "HDBSCAN clusters with a support test, dense depth-warp evidence, confirmation over frames;\n"
      "include/ds3d/geometric_motion.hpp). detect(rgb, depth, camera, timestamp) as every\n"
      "ds3d.DynamicObjectSource; returns DynamicObjects with boxes_3d (camera frame). Keeps "
      "state:\n"
      "frames in order, one sequence per instance. Deterministic.")
      .def(py::init<const GeometricMotionParams&>(), py::arg("params") = GeometricMotionParams{},
           "ValueError naming the bad field of params.")
      .def_property_readonly(
          "params", [](const GeometricMotionSource& s) { return s.params(); },
          "the validated GeometricMotionParams (a copy)")
      .def_property_readonly(
          "last_stats", [](const GeometricMotionSource& s) { return s.last_stats(); },
          "ds3d.GeometricMotionStats of the last detect() call (a copy).")
      .def_property_readonly(
          "last_tested",
          [](const GeometricMotionSource& s) { return tested_array(s.last_tested()); },
          "Structured (N,) array of the keypoints chi2-tested in the last detect() call: u v [px,\n"
          "raw], z [m], chi2 (float32), moving (bool), cluster (int32, -1 = none), candidate "
          "(bool).\n"
          "Empty without a trusted pose.")
      .def_property_readonly(
          "last_moving_pixels",
          [](const GeometricMotionSource& s) { return pixels_array(s.last_moving_pixels()); },
          "(M, 2) float32 warp grid pixels (u, v) flagged as moved into empty space in the last\n"
          "detect() call.")
      .def_property_readonly(
          "last_warp_tested",
          [](const GeometricMotionSource& s) { return pixels_array(s.last_warp_tested()); },
          "(T, 2) float32 warp grid pixels (u, v) the dense depth warp tested in the last "
          "detect()\n"
          "call, flagged or not (a superset of last_moving_pixels).");
}
