// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/slam/slam_frontend.hpp (ds3d.Slam, ds3d.FrontendConfig,
// ds3d.TrackResult, ds3d.KeypointStatus, ds3d._run_slam). Conveniences (argument handling of
// Slam and run_slam, SlamResult) live in python/ds3d/slam.py.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <memory>
#include <optional>
#include <string>

#include "../numpy_util.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/slam/config.hpp"
#include "ds3d/slam/dataset.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/slam/slam_frontend.hpp"
#include "slam_py_util.hpp"

namespace py = pybind11;
using ds3d::slam::FrontendConfig;
using ds3d::slam::KeypointStatus;
using ds3d::slam::TrackResult;

namespace {

// (N, 8) float64: timestamp tx ty tz qx qy qz qw (TUM order, camera-to-world).
py::array_t<double> poses_to_array(const std::vector<ds3d::slam::FramePose>& poses) {
  py::array_t<double> out({static_cast<py::ssize_t>(poses.size()), static_cast<py::ssize_t>(8)});
  auto a = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const auto& p = poses[i];
    const Eigen::Quaterniond q(p.T_world_cam.linear());
    const Eigen::Vector3d t = p.T_world_cam.translation();
    const auto r = static_cast<py::ssize_t>(i);
    a(r, 0) = p.timestamp;
    a(r, 1) = t.x();
    a(r, 2) = t.y();
    a(r, 3) = t.z();
    a(r, 4) = q.x();
    a(r, 5) = q.y();
    a(r, 6) = q.z();
    a(r, 7) = q.w();
  }
  return out;
}

py::array_t<double> matrix4(const Eigen::Isometry3d& T) {
  py::array_t<double> out({4, 4});
  auto a = out.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) a(r, c) = T.matrix()(r, c);
  }
  return out;
}

py::array_t<float> keypoint_rows(const std::vector<cv::Point2f>& kp) {
  py::array_t<float> out({static_cast<py::ssize_t>(kp.size()), static_cast<py::ssize_t>(2)});
  auto a = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < kp.size(); ++i) {
    a(static_cast<py::ssize_t>(i), 0) = kp[i].x;
    a(static_cast<py::ssize_t>(i), 1) = kp[i].y;
  }
  return out;
}

py::array_t<std::uint8_t> status_array(const std::vector<KeypointStatus>& s) {
  py::array_t<std::uint8_t> out(static_cast<py::ssize_t>(s.size()));
  for (std::size_t i = 0; i < s.size(); ++i) {
    out.mutable_data()[i] = static_cast<std::uint8_t>(s[i]);
  }
  return out;
}

// A Python-facing wrapper that remembers the last result for inspection.
class PySlam {
 public:
  PySlam(const FrontendConfig& cfg, std::shared_ptr<ds3d::slam::DynamicObjectSource> source,
         std::shared_ptr<ds3d::slam::HdbscanMasker> masker)
      : slam_(cfg, std::move(source), std::move(masker)) {}
  py::object track(
      const py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>& rgb,
      const std::optional<py::array_t<std::uint16_t, py::array::c_style | py::array::forcecast>>&
          depth,
      double timestamp, bool return_result) {
    constexpr const char* fn = "ds3d.Slam.track";
    DS3D_CHECK(rgb.ndim() == 3 && rgb.shape(2) == 3, fn,
               ": rgb must be an (H, W, 3) uint8 BGR array (got ", rgb.ndim(), " dimensions)");
    // Owned copies: the dynamic source may keep past frames, and Python may reuse the arrays.
    const cv::Mat rgb_mat = cv::Mat(static_cast<int>(rgb.shape(0)), static_cast<int>(rgb.shape(1)),
                                    CV_8UC3, const_cast<std::uint8_t*>(rgb.data()))
                                .clone();
    cv::Mat depth_mat;
    if (depth) {
      DS3D_CHECK(depth->ndim() == 2, fn, ": depth must be an (H, W) uint16 array (got ",
                 depth->ndim(), " dimensions)");
      depth_mat = cv::Mat(static_cast<int>(depth->shape(0)), static_cast<int>(depth->shape(1)),
                          CV_16UC1, const_cast<std::uint16_t*>(depth->data()))
                      .clone();
    }
    {
      const py::gil_scoped_release release;
      last_ = slam_.track(rgb_mat, depth_mat, timestamp);
    }
    if (return_result) return py::cast(last_);
    return matrix4(last_.T_world_cam);
  }
  ds3d::slam::SlamFrontend& slam() { return slam_; }
  const TrackResult& last() const { return last_; }

 private:
  ds3d::slam::SlamFrontend slam_;
  TrackResult last_;
};

// Per-frame figures of a run, one entry per tracked frame.
struct PerFrame {
  std::vector<std::int64_t> index;
  std::vector<double> timestamp;
  std::vector<std::string> state;
  std::vector<std::uint8_t> tracked, keyframe;
  std::vector<std::int32_t> features, dynamic, refilled, depth_edge, inliers;

  void add(const TrackResult& r) {
    index.push_back(static_cast<std::int64_t>(r.index));
    timestamp.push_back(r.timestamp);
    state.emplace_back(ds3d::slam::to_string(r.state));
    tracked.push_back(r.tracked ? 1 : 0);
    keyframe.push_back(r.keyframe ? 1 : 0);
    features.push_back(r.num_features);
    dynamic.push_back(r.num_dynamic);
    refilled.push_back(r.num_refilled);
    depth_edge.push_back(r.num_depth_edge);
    inliers.push_back(r.num_inliers);
  }
  [[nodiscard]] py::dict to_dict() const {
    namespace pu = ds3d::py_util;
    const auto np = py::module_::import("numpy");
    py::dict d;
    d["index"] = pu::to_numpy(index);
    d["timestamp"] = pu::to_numpy(timestamp);
    d["state"] = np.attr("array")(py::cast(state), "U16");
    d["tracked"] = pu::to_numpy(tracked).attr("astype")("bool");
    d["keyframe"] = pu::to_numpy(keyframe).attr("astype")("bool");
    d["features"] = pu::to_numpy(features);
    d["dynamic"] = pu::to_numpy(dynamic);
    d["refilled"] = pu::to_numpy(refilled);
    d["depth_edge"] = pu::to_numpy(depth_edge);
    d["inliers"] = pu::to_numpy(inliers);
    return d;
  }
};

// The on_result hook of _run_slam (runs on the calling thread): calls the Python callback with the
// GIL and turns a KeyboardInterrupt, raised by it or by a pending SIGINT, into a stop request; any
// other Python exception also stops the run and is rethrown once the pipeline has ended.
class RunMonitor {
 public:
  RunMonitor(py::object on_frame, std::size_t total)
      : on_frame_(std::move(on_frame)), total_(total) {}
  void operator()(const TrackResult& r) {
    per_frame_.add(r);
    if (stop_) return;
    const py::gil_scoped_acquire gil;
    try {
      if (!on_frame_.is_none()) on_frame_(r, per_frame_.index.size(), total_);
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    } catch (py::error_already_set& e) {
      stop_ = true;
      if (!e.matches(PyExc_KeyboardInterrupt)) error_ = std::make_unique<py::error_already_set>(e);
    }
  }
  [[nodiscard]] bool stop_requested() const { return stop_; }
  /// Rethrows the callback's error, if any; call with the GIL held.
  void rethrow() {
    if (error_) throw py::error_already_set(*error_);
  }
  [[nodiscard]] const PerFrame& per_frame() const { return per_frame_; }
  [[nodiscard]] bool interrupted() const { return stop_ && !error_; }

 private:
  py::object on_frame_;
  std::size_t total_;
  PerFrame per_frame_;
  std::atomic<bool> stop_{false};
  std::unique_ptr<py::error_already_set> error_;
};

// ds3d-slam's path: source, masker, SlamFrontend(cfg, source, masker), run_pipeline.
py::dict run_slam(const py::object& dataset_dir, const py::object& camera, std::size_t max_frames,
                  const ds3d::slam::SlamConfig& c, const py::object& on_frame) {
  c.validate();
  // The source first, as ds3d-slam does: bad options fail before any image is read.
  auto source = ds3d::slam::make_dynamic_source(c);
  auto masker = ds3d::slam::make_masker(c);
  ds3d::DatasetOptions opt;
  if (!camera.is_none()) opt.camera = ds3d::py_camera::camera_from("ds3d.run_slam", camera);
  const auto ds = ds3d::RgbdDataset::open(ds3d::py_slam::path_from(dataset_dir), opt);
  FrontendConfig cfg = c.frontend;
  cfg.camera = ds.camera();
  ds3d::slam::SlamFrontend slam(cfg, source, masker);
  const std::size_t total = max_frames == 0 ? ds.size() : std::min(max_frames, ds.size());
  RunMonitor monitor(on_frame, total);
  std::size_t next_index = 0;
  // Frames are read here (as ds3d-slam does) so that a stop request ends the input: the frames
  // read so far are still tracked and finished.
  const auto next = [&]() -> std::optional<ds3d::slam::FrameInput> {
    if (next_index >= total || monitor.stop_requested()) return std::nullopt;
    return ds3d::slam::to_frame_input(ds.frame(next_index++));
  };
  {
    const py::gil_scoped_release release;
    (void)ds3d::slam::run_pipeline(slam, next, std::ref(monitor), c.pipeline);
  }
  monitor.rethrow();
  py::dict out;
  out["trajectory"] = poses_to_array(slam.trajectory());
  out["keyframes"] = poses_to_array(slam.keyframe_trajectory());
  out["per_frame"] = monitor.per_frame().to_dict();
  out["stopped_early"] = monitor.interrupted() && monitor.per_frame().index.size() < total;
  out["total"] = total;
  return out;
}

void bind_track_result(py::module_& m) {
  py::enum_<KeypointStatus>(m, "KeypointStatus", py::arithmetic(),
                            "What became of a keypoint (TrackResult.keypoint_status values).")
      .value("unmatched", KeypointStatus::kUnmatched, "used for tracking, not matched")
      .value("tracked", KeypointStatus::kTracked, "an inlier of the pose")
      .value("dynamic", KeypointStatus::kDynamic, "removed by the dynamic filter")
      .value("depth_edge", KeypointStatus::kDepthEdge,
             "removed on a depth edge (frontend.depth_edge_ratio)");
  py::class_<TrackResult>(m, "TrackResult",
                          "The outcome of tracking one frame (include/ds3d/slam/slam_frontend.hpp "
                          "TrackResult): from Slam.track(..., return_result=True), "
                          "Slam.last_result and run_slam(progress=callable).")
      .def_readonly("index", &TrackResult::index, "frame index")
      .def_readonly("timestamp", &TrackResult::timestamp, "[s]")
      .def_property_readonly(
          "pose", [](const TrackResult& r) { return matrix4(r.T_world_cam); },
          "(4, 4) float64 camera-to-world online estimate (the last known one when lost)")
      .def_property_readonly(
          "state", [](const TrackResult& r) { return std::string(ds3d::slam::to_string(r.state)); },
          "'not_initialized', 'initialized', 'tracking', 'relocalized', 'lost' or 'reanchored'")
      .def_readonly("tracked", &TrackResult::tracked, "state is initialized/tracking/relocalized")
      .def_readonly("keyframe", &TrackResult::keyframe, "this frame became a keyframe")
      .def_readonly("odometry", &TrackResult::odometry, "pose from the odometry fallback")
      .def_readonly("motion_gated", &TrackResult::motion_gated,
                    "the first pose broke the motion bounds; the one tracked from the "
                    "constant-velocity prediction replaced it")
      .def_readonly("num_features", &TrackResult::num_features, "keypoints extracted")
      .def_readonly("num_dynamic", &TrackResult::num_dynamic,
                    "keypoints the dynamic filter removed")
      .def_readonly("num_refilled", &TrackResult::num_refilled, "spare keypoints added")
      .def_readonly("num_depth_edge", &TrackResult::num_depth_edge,
                    "keypoints removed on depth edges")
      .def_readonly("num_inliers", &TrackResult::num_inliers, "map-point matches kept")
      .def_property_readonly(
          "keypoints", [](const TrackResult& r) { return keypoint_rows(r.keypoints); },
          "(N, 2) float32 raw pixel (u, v) of every extracted keypoint")
      .def_property_readonly(
          "keypoint_status", [](const TrackResult& r) { return status_array(r.keypoint_status); },
          "(N,) uint8 ds3d.KeypointStatus value per keypoint (0 unmatched, 1 tracked, 2 dynamic, "
          "3 depth_edge)")
      .def_property_readonly(
          "dynamic",
          [](const TrackResult& r) {
            py::array_t<bool> a(static_cast<py::ssize_t>(r.keypoint_status.size()));
            for (std::size_t i = 0; i < r.keypoint_status.size(); ++i) {
              a.mutable_data()[i] = r.keypoint_status[i] == KeypointStatus::kDynamic;
            }
            return a;
          },
          "(N,) bool: keypoint_status == KeypointStatus.dynamic")
      .def_property_readonly(
          "times",
          [](const TrackResult& r) {
            py::dict d;
            d["extract_ms"] = r.times.extract_ms;
            d["detect_ms"] = r.times.detect_ms;
            d["prepare_ms"] = r.times.prepare_ms;
            d["filter_ms"] = r.times.filter_ms;
            d["track_ms"] = r.times.track_ms;
            d["extract_cpu_ms"] = r.times.extract_cpu_ms;
            d["track_cpu_ms"] = r.times.track_cpu_ms;
            d["detect_cpu_ms"] = r.times.detect_cpu_ms;
            d["prepare_cpu_ms"] = r.times.prepare_cpu_ms;
            return d;
          },
          "stage times [ms]: extract_ms detect_ms filter_ms track_ms (wall; prepare_ms: the part "
          "of detect_ms in the source's prepare()), extract_cpu_ms track_cpu_ms detect_cpu_ms "
          "prepare_cpu_ms (thread CPU)")
      .def("__repr__", [](const TrackResult& r) {
        return "TrackResult(index=" + std::to_string(r.index) + ", state='" +
               ds3d::slam::to_string(r.state) + "', features=" + std::to_string(r.num_features) +
               ", dynamic=" + std::to_string(r.num_dynamic) +
               ", inliers=" + std::to_string(r.num_inliers) + ")";
      });
}

void bind_slam_class(py::module_& m) {
  py::class_<PySlam>(
      m, "Slam",
      "ORB + Ceres RGB-D SLAM front-end (include/ds3d/slam_frontend.hpp SlamFrontend).\n"
      "Slam(config=FrontendConfig(), source=None, masker=None); track(rgb, depth, timestamp) ->\n"
      "4x4 camera-to-world. ds3d.Slam (python/ds3d/slam.py) also takes a SlamConfig, a camera\n"
      "and a dynamic spec.")
      .def(py::init<const FrontendConfig&, std::shared_ptr<ds3d::slam::DynamicObjectSource>,
                    std::shared_ptr<ds3d::slam::HdbscanMasker>>(),
           py::arg("config") = FrontendConfig{}, py::arg("source") = nullptr,
           py::arg("masker") = nullptr)
      .def("track", &PySlam::track, py::arg("rgb"), py::arg("depth"), py::arg("timestamp"),
           py::arg("return_result") = false,
           "Tracks one frame: rgb (H, W, 3) uint8 BGR, depth (H, W) uint16 in depth_scale units "
           "per metre (or None), timestamp [s] (non-decreasing). Runs the dynamic source and "
           "masker, then tracking. Returns the 4x4 camera-to-world pose (the last known one when "
           "tracking is lost; see last_state), or the ds3d.TrackResult with return_result=True. "
           "Raises ValueError on bad images or when time goes backwards.")
      .def_property_readonly(
          "last_result", [](const PySlam& s) { return s.last(); },
          "ds3d.TrackResult of the last track() call (pose, state, keypoints, keypoint_status).")
      .def_property_readonly(
          "last_state",
          [](const PySlam& s) { return std::string(ds3d::slam::to_string(s.last().state)); })
      .def_property_readonly("last_tracked", [](const PySlam& s) { return s.last().tracked; })
      .def_property_readonly("last_num_inliers",
                             [](const PySlam& s) { return s.last().num_inliers; })
      .def(
          "finish", [](PySlam& s) { s.slam().finish(); }, py::call_guard<py::gil_scoped_release>(),
          "Applies pending and final bundle adjustment; call after the last frame.")
      .def(
          "trajectory", [](PySlam& s) { return poses_to_array(s.slam().trajectory()); },
          "(N, 8) float64: timestamp tx ty tz qx qy qz qw per input frame (camera-to-world).")
      .def(
          "keyframe_trajectory",
          [](PySlam& s) { return poses_to_array(s.slam().keyframe_trajectory()); },
          "(K, 8) float64 keyframe poses, same layout as trajectory().")
      .def(
          "map_points", [](PySlam& s) { return ds3d::Points3f(s.slam().map_points()); },
          "(M, 3) float32 map points [m, world].")
      .def_property_readonly("num_keyframes", [](PySlam& s) { return s.slam().num_keyframes(); })
      .def_property_readonly(
          "num_culled_keyframes", [](PySlam& s) { return s.slam().culled_keyframes().size(); },
          "Keyframes removed by keyframe culling (FrontendConfig.cull_keyframes) so far.")
      .def_property_readonly(
          "merged_segments", [](PySlam& s) { return s.slam().merged_segments(); },
          "Re-anchored map segments finish() moved back onto another segment's map "
          "(FrontendConfig.merge_segments).")
      .def_property_readonly(
          "interpolated_frames", [](PySlam& s) { return s.slam().interpolated_frames(); },
          "Frames whose pose finish() interpolated (FrontendConfig.interpolate_lost).")
      .def_property_readonly(
          "camera", [](PySlam& s) { return s.slam().config().camera; },
          "The ds3d.Camera of the front-end.");
}

}  // namespace

void bind_slam_frontend(py::module_& m) {
  py::class_<FrontendConfig>(
      m, "FrontendConfig",
      "Configuration of ds3d.Slam (include/ds3d/slam_frontend.hpp FrontendConfig).\n"
      "Camera fields are flattened: fx fy cx cy width height k1 k2 p1 p2 k3 depth_scale.")
      .def(py::init<>())
#define DS3D_CAM_FIELD(name)                                        \
  def_property(                                                     \
      #name, [](const FrontendConfig& c) { return c.camera.name; }, \
      [](FrontendConfig& c, decltype(ds3d::PinholeCamera::name) v) { c.camera.name = v; })
      .DS3D_CAM_FIELD(fx)
      .DS3D_CAM_FIELD(fy)
      .DS3D_CAM_FIELD(cx)
      .DS3D_CAM_FIELD(cy)
      .DS3D_CAM_FIELD(width)
      .DS3D_CAM_FIELD(height)
      .DS3D_CAM_FIELD(k1)
      .DS3D_CAM_FIELD(k2)
      .DS3D_CAM_FIELD(p1)
      .DS3D_CAM_FIELD(p2)
      .DS3D_CAM_FIELD(k3)
      .DS3D_CAM_FIELD(depth_scale)
#undef DS3D_CAM_FIELD
      .def(
          "set_camera",
          [](FrontendConfig& c, const py::object& spec) {
            c.camera = ds3d::py_camera::camera_from("ds3d.FrontendConfig.set_camera", spec);
          },
          py::arg("spec"),
          "Camera from a ds3d.Camera, a dict, a preset name (tum1 tum2 tum3 tum_ros bonn) or a "
          "camera.txt path.")
      .def_property(
          "camera", [](const FrontendConfig& c) { return c.camera; },
          [](FrontendConfig& c, const py::object& spec) {
            c.camera = ds3d::py_camera::camera_from("ds3d.FrontendConfig.camera", spec);
          },
          "The ds3d.Camera (a copy); assign a Camera, a dict, a preset name or a camera.txt path.")
      .def_property(
          "num_features", [](const FrontendConfig& c) { return c.orb.num_features; },
          [](FrontendConfig& c, int v) { c.orb.num_features = v; })
      .def_property(
          "num_levels", [](const FrontendConfig& c) { return c.orb.num_levels; },
          [](FrontendConfig& c, int v) { c.orb.num_levels = v; })
      .def_property(
          "close_depth", [](const FrontendConfig& c) { return c.orb.max_depth; },
          [](FrontendConfig& c, double v) { c.orb.max_depth = v; })
      .def_readwrite("bf", &FrontendConfig::bf)
      .def_readwrite("min_init_points", &FrontendConfig::min_init_points)
      .def_readwrite("min_tracked_inliers", &FrontendConfig::min_tracked_inliers)
      .def_readwrite("keyframe_max_gap", &FrontendConfig::keyframe_max_gap)
      .def_readwrite("local_window", &FrontendConfig::local_window)
      .def_readwrite("enable_local_ba", &FrontendConfig::enable_local_ba)
      .def_readwrite("mapping_thread", &FrontendConfig::mapping_thread)
      .def_readwrite("final_global_ba", &FrontendConfig::final_global_ba)
      .def_readwrite("ba_apply_lag", &FrontendConfig::ba_apply_lag)
      .def_readwrite("relocalisation_candidates", &FrontendConfig::relocalisation_candidates)
      .def_readwrite("reanchor_after_lost", &FrontendConfig::reanchor_after_lost)
      .def_readwrite("fuse_neighbors", &FrontendConfig::fuse_neighbors)
      .def_readwrite("keyframe_ref_ratio", &FrontendConfig::keyframe_ref_ratio)
      .def_readwrite("refine_frame_poses", &FrontendConfig::refine_frame_poses)
      .def_readwrite("refine_rounds", &FrontendConfig::refine_rounds)
      .def_readwrite("smooth_acceleration", &FrontendConfig::smooth_acceleration)
      .def_readwrite("merge_segments", &FrontendConfig::merge_segments)
      .def_readwrite("interpolate_lost", &FrontendConfig::interpolate_lost)
      .def_readwrite("cull_keyframes", &FrontendConfig::cull_keyframes)
      .def_readwrite("keyframe_redundancy_ratio", &FrontendConfig::keyframe_redundancy_ratio)
      .def_readwrite("keyframe_redundant_observers", &FrontendConfig::keyframe_redundant_observers)
      .def("validate", &FrontendConfig::validate, "Raises ValueError naming the bad field.")
      .def(
          "copy", [](const FrontendConfig& c) { return FrontendConfig(c); }, "A copy.")
      .def("__copy__", [](const FrontendConfig& c) { return FrontendConfig(c); });

  bind_track_result(m);
  bind_slam_class(m);
  m.def("_run_slam", &run_slam, py::arg("dataset_dir"), py::arg("camera"), py::arg("max_frames"),
        py::arg("config"), py::arg("on_frame") = py::none(),
        "Internal: see ds3d.run_slam. Returns a dict: trajectory, keyframes, per_frame, "
        "stopped_early, total.");
}
