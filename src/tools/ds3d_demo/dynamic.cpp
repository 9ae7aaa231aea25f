// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Demo step 60: a synthetic walking sequence tracked with and without dynamic-feature removal:
// keypoint precision/recall against the generator's masks, ATE, trajectory files and a top-view
// SVG plot of the trajectories.
#include <cstdint>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wrestrict"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/slam/dynamic/geometric_motion.hpp"
#include "ds3d/slam/slam_frontend.hpp"
#include "ds3d/slam/synth.hpp"
#pragma GCC diagnostic pop
#include "ds3d_demo/demo.hpp"

namespace {

// Ground-truth humanoid boxes as 3-D boxes in the camera frame: an oracle 3-D detector.
class OracleSource final : public ds3d::slam::DynamicObjectSource {
 public:
  explicit OracleSource(const ds3d::synth::SyntheticScene& scene) : scene_(scene) {}
  ds3d::slam::DynamicObjects detect(const ds3d::slam::FrameInput& frame,
                                    const ds3d::PinholeCamera&) override {
    ds3d::slam::DynamicObjects out;
    const auto f = scene_.render(frame.index);
    const Eigen::Isometry3d T_cam_world = f.T_world_cam.inverse();
    for (const auto& b : f.boxes) {
      if (b.visible_pixels == 0) continue;
      const Eigen::Matrix3d R =
          Eigen::AngleAxisd(b.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      Eigen::Matrix<float, 8, 3> c;
      for (int k = 0; k < 8; ++k) {
        const Eigen::Vector3d local((k & 1) != 0 ? 0.5 : -0.5, (k & 2) != 0 ? 0.5 : -0.5,
                                    (k & 4) != 0 ? 0.5 : -0.5);
        const Eigen::Vector3d p = b.center + R * local.cwiseProduct(b.size);
        c.row(k) = (T_cam_world * p).cast<float>().transpose();
      }
      out.boxes_3d.push_back(c);
    }
    return out;
  }
  [[nodiscard]] std::string name() const override { return "oracle"; }

 private:
  const ds3d::synth::SyntheticScene& scene_;
};

struct Row {
  std::string mode;
  double precision = 0, recall = 0, ate = 0;
  ds3d::Trajectory traj;
};

Row run_mode(const std::string& mode, const ds3d::synth::SyntheticScene& scene) {
  ds3d::slam::FrontendConfig cfg;
  cfg.camera = scene.options().camera;
  std::shared_ptr<ds3d::slam::DynamicObjectSource> src;
  std::shared_ptr<ds3d::slam::DynamicFeatureMasker> masker;
  if (mode == "oracle-boxes") src = std::make_shared<OracleSource>(scene);
  if (mode == "geometric") src = std::make_shared<ds3d::slam::GeometricMotionSource>();
  if (mode == "htx" || mode == "htx+geometric") src = ds3d::slam::make_dynamic_source(mode);
  if (src) masker = std::make_shared<ds3d::slam::HdbscanMasker>();
  ds3d::slam::SlamFrontend slam(cfg, src, masker);
  std::int64_t tp = 0, fp = 0, fn = 0;
  ds3d::Trajectory gt;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const auto f = scene.render(i);
    const auto r = slam.track(f.rgb, f.depth, f.timestamp);
    for (std::size_t k = 0; k < r.keypoints.size(); ++k) {
      const int u = std::clamp(static_cast<int>(std::lround(r.keypoints[k].x)), 0, f.rgb.cols - 1);
      const int v = std::clamp(static_cast<int>(std::lround(r.keypoints[k].y)), 0, f.rgb.rows - 1);
      const bool truth = f.dynamic_mask.at<std::uint8_t>(v, u) != 0U;
      const bool pred = r.keypoint_status[k] == ds3d::slam::KeypointStatus::kDynamic;
      tp += (truth && pred) ? 1 : 0;
      fp += (!truth && pred) ? 1 : 0;
      fn += (truth && !pred) ? 1 : 0;
    }
  }
  slam.finish();
  Row row;
  row.mode = mode;
  row.precision = tp + fp > 0 ? static_cast<double>(tp) / static_cast<double>(tp + fp) : 1.0;
  row.recall = tp + fn > 0 ? static_cast<double>(tp) / static_cast<double>(tp + fn) : 1.0;
  row.traj = ds3d::slam::to_trajectory(slam.trajectory());
  return row;
}

void write_svg(const std::filesystem::path& path, const ds3d::Trajectory& gt,
               const std::vector<Row>& rows, const std::vector<ds3d::AteResult>& ate) {
  // Top view (x, y of the aligned estimates against the groundtruth), auto-scaled.
  const char* colours[] = {"#d62728", "#2ca02c", "#1f77b4", "#9467bd", "#ff7f0e"};
  double x0 = 1e30, x1 = -1e30, y0 = 1e30, y1 = -1e30;
  for (const auto& p : gt) {
    x0 = std::min(x0, p.T_world_cam.translation().x());
    x1 = std::max(x1, p.T_world_cam.translation().x());
    y0 = std::min(y0, p.T_world_cam.translation().y());
    y1 = std::max(y1, p.T_world_cam.translation().y());
  }
  const double pad = 0.2 * std::max(x1 - x0, y1 - y0) + 0.05;
  x0 -= pad, x1 += pad, y0 -= pad, y1 += pad;
  const double s = 480.0 / std::max(x1 - x0, y1 - y0);
  std::ofstream out(path);
  out << "<svg xmlns='http://www.w3.org/2000/svg' width='520' height='600'>\n"
      << "<rect width='100%' height='100%' fill='white'/>\n";
  const auto polyline = [&](const std::vector<Eigen::Vector3d>& pts, const char* colour) {
    out << "<polyline fill='none' stroke='" << colour << "' stroke-width='1.5' points='";
    for (const auto& p : pts) out << 20 + s * (p.x() - x0) << "," << 500 - s * (p.y() - y0) << " ";
    out << "'/>\n";
  };
  std::vector<Eigen::Vector3d> g;
  for (const auto& p : gt) g.push_back(p.T_world_cam.translation());
  polyline(g, "black");
  for (std::size_t m = 0; m < rows.size(); ++m) {
    std::vector<Eigen::Vector3d> e;
    for (const auto& match : ate[m].matches) e.push_back(match.p_est);
    polyline(e, colours[m % 5]);
    out << "<text x='20' y='" << 525 + 12 * static_cast<int>(m) << "' font-size='11' fill='"
        << colours[m % 5] << "'>" << rows[m].mode << ": ATE " << ate[m].rmse << " m</text>\n";
  }
  out << "<text x='300' y='525' font-size='11'>black: groundtruth (top view)</text>\n</svg>\n";
}

}  // namespace

DS3D_DEMO_STEP(
    60, "dynamic-feature removal: SLAM on a synthetic walking sequence",
    [](const ds3d::demo::Context& ctx) {
      ds3d::synth::SynthOptions opt;
      opt.scenario = ds3d::synth::Scenario::kWalkingXyz;
      opt.num_frames = ctx.quick ? 60 : 240;
      opt.seed = ctx.seed;
      const ds3d::synth::SyntheticScene scene(opt);
      ds3d::Trajectory gt;
      for (std::size_t i = 0; i < scene.size(); ++i) {
        gt.push_back({scene.timestamp(i), scene.camera_pose(scene.timestamp(i))});
      }
      std::vector<Row> rows;
      std::vector<ds3d::AteResult> ate;
      for (const char* mode : {"none", "oracle-boxes", "geometric", "htx", "htx+geometric"}) {
        rows.push_back(run_mode(mode, scene));
        ate.push_back(ds3d::evaluate_ate(gt, rows.back().traj));
        ds3d::write_tum_trajectory(ctx.out_dir / ("dynamic_" + rows.back().mode + ".txt"),
                                   rows.back().traj);
      }
      ds3d::write_tum_trajectory(ctx.out_dir / "dynamic_groundtruth.txt", gt);
      write_svg(ctx.out_dir / "dynamic_trajectories.svg", gt, rows, ate);
      std::cout << "walking_xyz, " << scene.size() << " frames (seed " << ctx.seed
                << ")\n| --dynamic | keypoint precision | recall | ATE RMSE [m] |\n"
                << "|---|---|---|---|\n"
                << std::fixed << std::setprecision(3);
      for (std::size_t m = 0; m < rows.size(); ++m) {
        // `none` marks no keypoint: precision and recall are undefined there.
        if (rows[m].mode == "none") {
          std::cout << "| none | – | – | " << ate[m].rmse << " |\n";
        } else {
          std::cout << "| " << rows[m].mode << " | " << rows[m].precision << " | " << rows[m].recall
                    << " | " << ate[m].rmse << " |\n";
        }
      }
      std::cout << "trajectories and dynamic_trajectories.svg written to " << ctx.out_dir.string()
                << "\n";
    });
