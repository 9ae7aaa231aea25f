// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// SLAM front-end stages on generated frames (ds3d::synth static_room, 640x480): ORB extraction,
// pose-only optimisation, and whole-sequence tracking (threaded pipeline vs single thread).
#include <benchmark/benchmark.h>

#include <opencv2/core/utility.hpp>

#include "ds3d/slam/bundle_adjustment.hpp"
#include "ds3d/slam/orb_features.hpp"
#include "ds3d/slam/slam_frontend.hpp"
#include "ds3d/slam/synth.hpp"
#include "support/synth_frames.hpp"
#include "support/synthetic.hpp"

namespace {

const std::vector<ds3d::synth::SynthFrame>& frames() {
  static const std::vector<ds3d::synth::SynthFrame> f =
      ds3d::test::render_sequence(ds3d::synth::Scenario::kStaticRoom, 30);
  return f;
}

void BM_OrbExtract(benchmark::State& state) {
  cv::setNumThreads(1);
  ds3d::slam::OrbParams p;
  p.num_features = static_cast<int>(state.range(0));
  const ds3d::slam::OrbExtractor ex(p);
  const auto& f = frames()[0];
  const ds3d::PinholeCamera cam = ds3d::synth::SynthOptions{}.camera;
  std::size_t n = 0;
  for (auto _ : state) {
    auto r = ex.extract(f.rgb, f.depth, cam);
    n = r.size();
    benchmark::DoNotOptimize(r);
  }
  state.counters["keypoints"] = static_cast<double>(n);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_OrbExtract)->Arg(1000)->Arg(2000)->Unit(benchmark::kMillisecond);

void BM_OptimizePose(benchmark::State& state) {
  ds3d::test::Rng rng(1);
  const ds3d::slam::StereoIntrinsics k{525, 525, 319.5, 239.5, 40};
  std::vector<Eigen::Vector3d> pts;
  std::vector<ds3d::slam::Observation> obs;
  for (int i = 0; i < state.range(0); ++i) {
    const Eigen::Vector3d p(rng.uniform(-1.5, 1.5), rng.uniform(-1, 1), rng.uniform(1, 4));
    ds3d::slam::Observation o;
    o.pixel = {k.fx * p.x() / p.z() + k.cx + rng.normal(),
               k.fy * p.y() / p.z() + k.cy + rng.normal()};
    o.has_depth = true;
    o.u_right = o.pixel.x() - k.bf / p.z();
    pts.push_back(p);
    obs.push_back(o);
  }
  Eigen::Isometry3d init = Eigen::Isometry3d::Identity();
  init.translation() = Eigen::Vector3d(0.02, -0.01, 0.03);
  for (auto _ : state) benchmark::DoNotOptimize(ds3d::slam::optimize_pose(k, init, pts, obs));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_OptimizePose)->Arg(300)->Arg(1000)->Unit(benchmark::kMillisecond);

// Whole pipeline over 30 frames; arg 1 = threaded stages + mapping thread, 0 = one thread.
void BM_TrackSequence(benchmark::State& state) {
  cv::setNumThreads(1);
  const bool threaded = state.range(0) != 0;
  for (auto _ : state) {
    ds3d::slam::FrontendConfig cfg;
    cfg.camera = ds3d::synth::SynthOptions{}.camera;
    cfg.mapping_thread = threaded;
    cfg.final_global_ba = false;
    cfg.refine_frame_poses = false;  // per-frame work only: BM_Finish measures finish()
    ds3d::slam::SlamFrontend slam(cfg);
    std::size_t i = 0;
    const auto next = [&]() -> std::optional<ds3d::slam::FrameInput> {
      if (i >= frames().size()) return std::nullopt;
      ds3d::slam::FrameInput in;
      in.index = i;
      in.timestamp = frames()[i].timestamp;
      in.rgb = frames()[i].rgb;
      in.depth = frames()[i].depth;
      ++i;
      return in;
    };
    ds3d::slam::PipelineOptions po;
    po.threaded = threaded;
    benchmark::DoNotOptimize(ds3d::slam::run_pipeline(slam, next, {}, po));
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(frames().size()));
}
BENCHMARK(BM_TrackSequence)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(2);

// finish() after 30 tracked frames (tracking itself is not timed): arg 0 = global BA only,
// 1 = + per-frame pose refinement, 2 = + refinement with the default 2 point rounds.
void BM_Finish(benchmark::State& state) {
  cv::setNumThreads(1);
  for (auto _ : state) {
    state.PauseTiming();
    ds3d::slam::FrontendConfig cfg;
    cfg.camera = ds3d::synth::SynthOptions{}.camera;
    cfg.mapping_thread = false;
    cfg.refine_frame_poses = state.range(0) > 0;
    cfg.refine_rounds = state.range(0) > 1 ? 2 : 0;
    ds3d::slam::SlamFrontend slam(cfg);
    for (const auto& f : frames()) (void)slam.track(f.rgb, f.depth, f.timestamp);
    state.ResumeTiming();
    slam.finish();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(frames().size()));
}
BENCHMARK(BM_Finish)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace
