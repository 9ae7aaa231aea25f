// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Demo step 50: the RGB-D SLAM front-end on a generated static-room sequence, with its ATE.
#include <iostream>

// GCC 12 -O3 false -Wrestrict in trajectory.hpp's file writer (see ds3d_slam.cpp).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wrestrict"
#include "ds3d/slam/slam_frontend.hpp"
#include "ds3d/slam/synth.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#pragma GCC diagnostic pop
#include "ds3d_demo/demo.hpp"

DS3D_DEMO_STEP(50, "SLAM front-end: ORB + Ceres on a generated sequence",
               [](const ds3d::demo::Context& ctx) {
                 ds3d::synth::SynthOptions o;
                 o.scenario = ds3d::synth::Scenario::kStaticRoom;
                 o.num_frames = ctx.quick ? 30 : 90;
                 o.seed = ctx.seed;
                 const ds3d::synth::SyntheticScene scene(o);
                 ds3d::slam::FrontendConfig cfg;
                 cfg.camera = o.camera;
                 ds3d::slam::SlamFrontend slam(cfg);
                 ds3d::Trajectory gt;
                 std::size_t i = 0;
                 const auto next = [&]() -> std::optional<ds3d::slam::FrameInput> {
                   if (i >= scene.size()) return std::nullopt;
                   auto f = scene.render(i);
                   gt.push_back({f.timestamp, f.T_world_cam});
                   ds3d::slam::FrameInput in;
                   in.index = i++;
                   in.timestamp = f.timestamp;
                   in.rgb = std::move(f.rgb);
                   in.depth = std::move(f.depth);
                   return in;
                 };
                 const auto results = ds3d::slam::run_pipeline(slam, next);
                 std::size_t tracked = 0;
                 for (const auto& r : results) tracked += r.tracked ? 1 : 0;
                 const auto est = ds3d::slam::to_trajectory(slam.trajectory());
                 const auto out = ctx.out_dir / "slam_static_room.txt";
                 ds3d::write_tum_trajectory(out, est);
                 const auto ate = ds3d::evaluate_ate(gt, est);
                 std::cout << "tracked " << tracked << " of " << results.size() << " frames of '"
                           << ds3d::synth::scenario_name(o.scenario) << "', "
                           << slam.num_keyframes() << " keyframes, " << slam.map_points().rows()
                           << " map points\n"
                           << "ATE RMSE " << ate.rmse * 1000.0 << " mm over "
                           << ate.compared_pose_pairs << " poses; trajectory written to "
                           << out.string() << "\n";
               });
