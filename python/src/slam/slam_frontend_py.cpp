// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/slam_frontend.hpp (ds3d.Slam, ds3d.SlamConfig, ds3d._run_slam).
// Conveniences (run_slam's argument handling) live in python/ds3d/slam.py.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>

#include "ds3d/slam/dataset.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/slam/slam_frontend.hpp"

namespace py = pybind11;
using ds3d::slam::FrontendConfig;

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

// A Python-facing wrapper that remembers the last result for inspection.
class PySlam {
 public:
  explicit PySlam(const FrontendConfig& cfg) : slam_(cfg) {}
  py::array_t<double> track(
      const py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>& rgb,
      const std::optional<py::array_t<std::uint16_t, py::array::c_style | py::array::forcecast>>&
          depth,
      double timestamp) {
    constexpr const char* fn = "ds3d.Slam.track";
    DS3D_CHECK(rgb.ndim() == 3 && rgb.shape(2) == 3, fn,
               ": rgb must be an (H, W, 3) uint8 BGR array (got ", rgb.ndim(), " dimensions)");
    const cv::Mat rgb_mat(static_cast<int>(rgb.shape(0)), static_cast<int>(rgb.shape(1)), CV_8UC3,
                          const_cast<std::uint8_t*>(rgb.data()));
    cv::Mat depth_mat;
    if (depth) {
      DS3D_CHECK(depth->ndim() == 2, fn, ": depth must be an (H, W) uint16 array (got ",
                 depth->ndim(), " dimensions)");
      depth_mat = cv::Mat(static_cast<int>(depth->shape(0)), static_cast<int>(depth->shape(1)),
                          CV_16UC1, const_cast<std::uint16_t*>(depth->data()));
    }
    {
      const py::gil_scoped_release release;
      last_ = slam_.track(rgb_mat, depth_mat, timestamp);
    }
    return matrix4(last_.T_world_cam);
  }
  ds3d::slam::SlamFrontend& slam() { return slam_; }
  const ds3d::slam::TrackResult& last() const { return last_; }

 private:
  ds3d::slam::SlamFrontend slam_;
  ds3d::slam::TrackResult last_;
};

ds3d::PinholeCamera camera_from(const std::string& spec) {
  if (spec == "tum1" || spec == "tum2" || spec == "tum3" || spec == "tum_ros" || spec == "bonn") {
    return ds3d::camera_preset(spec);
  }
  return ds3d::read_camera_file(spec);
}

}  // namespace

void bind_slam_frontend(py::module_& m) {
  py::class_<FrontendConfig>(
      m, "SlamConfig",
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
          [](FrontendConfig& c, const std::string& spec) { c.camera = camera_from(spec); },
          py::arg("spec"),
          "Camera from a preset name (tum1 tum2 tum3 tum_ros bonn) or a camera.txt path.")
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
      .def_readwrite("cull_keyframes", &FrontendConfig::cull_keyframes)
      .def_readwrite("keyframe_redundancy_ratio", &FrontendConfig::keyframe_redundancy_ratio)
      .def_readwrite("keyframe_redundant_observers", &FrontendConfig::keyframe_redundant_observers)
      .def("validate", &FrontendConfig::validate, "Raises ValueError naming the bad field.");

  py::class_<PySlam>(
      m, "Slam",
      "ORB + Ceres RGB-D SLAM front-end (include/ds3d/slam_frontend.hpp SlamFrontend).\n"
      "Slam(config=SlamConfig()); track(rgb, depth, timestamp) -> 4x4 camera-to-world.")
      .def(py::init<const FrontendConfig&>(), py::arg("config") = FrontendConfig{})
      .def(
          "track", &PySlam::track, py::arg("rgb"), py::arg("depth"), py::arg("timestamp"),
          "Tracks one frame: rgb (H, W, 3) uint8 BGR, depth (H, W) uint16 in depth_scale units per "
          "metre (or None), timestamp [s] (non-decreasing). Returns the 4x4 camera-to-world pose "
          "(the last known one when tracking is lost; see last_state). Raises ValueError on bad "
          "images or when time goes backwards.")
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
          "Keyframes removed by keyframe culling (SlamConfig.cull_keyframes) so far.");

  m.def(
      "_run_slam",
      [](const std::string& dataset_dir, const std::string& camera, std::size_t max_frames,
         bool threaded, std::optional<FrontendConfig> config, const std::string& dynamic,
         const std::string& weights, int detect_every, std::optional<float> min_score,
         std::optional<int> hold_frames, std::optional<int> segment_frames,
         bool segment_outside_boxes) {
        ds3d::slam::DynamicSourceOptions sopt;
        sopt.htx.segment_outside_boxes = segment_outside_boxes;
        if (segment_frames) sopt.htx.segment_frames = *segment_frames;
        sopt.weights = weights;
        sopt.htx.detect_every = detect_every;
        if (min_score) sopt.htx.min_score = *min_score;
        if (hold_frames) sopt.htx.hold_frames = *hold_frames;
        // The source first, as ds3d-slam does: bad options fail before any image is read.
        auto source = ds3d::slam::make_dynamic_source(dynamic, sopt);
        std::shared_ptr<ds3d::slam::DynamicFeatureMasker> masker;
        if (dynamic != "none") masker = std::make_shared<ds3d::slam::HdbscanMasker>();
        ds3d::DatasetOptions opt;
        if (!camera.empty()) opt.camera = camera_from(camera);
        const auto ds = ds3d::RgbdDataset::open(dataset_dir, opt);
        FrontendConfig cfg = config.value_or(FrontendConfig{});
        cfg.camera = ds.camera();
        ds3d::slam::SlamFrontend slam(cfg, source, masker);
        ds3d::slam::PipelineOptions po;
        po.threaded = threaded;
        std::vector<ds3d::slam::FramePose> poses;
        {
          const py::gil_scoped_release release;
          (void)ds3d::slam::run_dataset(slam, ds, max_frames, {}, po);
          poses = slam.trajectory();
        }
        return poses_to_array(poses);
      },
      py::arg("dataset_dir"), py::arg("camera") = "", py::arg("max_frames") = 0,
      py::arg("threaded") = true, py::arg("config") = py::none(), py::arg("dynamic") = "none",
      py::arg("weights") = "", py::arg("detect_every") = 1, py::arg("min_score") = py::none(),
      py::arg("hold_frames") = py::none(), py::arg("segment_frames") = py::none(),
      py::arg("segment_outside_boxes") = true, "Internal: see ds3d.run_slam.");
}
