// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Per-frame cost of GeometricMotionSource::detect (include/ds3d/geometric_motion.hpp) on a
// generated walking sequence (ds3d::synth walking_xyz, 640x480, two walkers, 30 frames): one
// iteration runs a fresh source over the whole sequence, so items/s is frames/s including the
// first frames (no reference yet); per-frame CPU = CPU time / 30. Args: image_scale x 100 (100 =
// default, 50 = ORB on a quarter of the pixels), segment_objects (1 = default: grow the pixel mask,
// 0 = boxes only).
#include <benchmark/benchmark.h>

#include <opencv2/core/utility.hpp>

#include "ds3d/slam/dynamic/geometric_motion.hpp"
#include "ds3d/slam/synth.hpp"
#include "support/synth_frames.hpp"

namespace {

const std::vector<ds3d::synth::SynthFrame>& frames() {
  static const std::vector<ds3d::synth::SynthFrame> f =
      ds3d::test::render_sequence(ds3d::synth::Scenario::kWalkingXyz, 30);
  return f;
}

void BM_GeometricMotionDetect(benchmark::State& state) {
  cv::setNumThreads(1);
  const ds3d::PinholeCamera cam = ds3d::synth::SynthOptions{}.camera;
  ds3d::slam::GeometricMotionParams p;
  p.image_scale = static_cast<double>(state.range(0)) / 100.0;
  p.segment_objects = state.range(1) != 0;
  std::size_t frames_with_objects = 0;
  std::int64_t moving_keypoints = 0;
  for (auto _ : state) {
    ds3d::slam::GeometricMotionSource src(p);
    frames_with_objects = 0;
    moving_keypoints = 0;
    for (const auto& f : frames()) {
      ds3d::slam::FrameInput in;
      in.index = f.index;
      in.timestamp = f.timestamp;
      in.rgb = f.rgb;
      in.depth = f.depth;
      const auto objects = src.detect(in, cam);
      frames_with_objects += objects.boxes_3d.empty() ? 0U : 1U;
      moving_keypoints += src.last_stats().num_moving_keypoints;
      benchmark::DoNotOptimize(objects.boxes_3d.data());
    }
  }
  const auto n = static_cast<std::int64_t>(frames().size());
  state.counters["frames_with_objects"] = static_cast<double>(frames_with_objects);
  state.counters["moving_kp_per_frame"] =
      static_cast<double>(moving_keypoints) / static_cast<double>(n);
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_GeometricMotionDetect)
    ->Args({100, 1})
    ->Args({100, 0})
    ->Args({50, 1})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

}  // namespace
