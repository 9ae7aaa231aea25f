// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ORB extraction (include/ds3d/orb_features.hpp) on a 640x480 generated frame (ds3d::synth
// walking_xyz frame 0: textured room and two walkers), by feature budget and pyramid depth, grey
// versus colour input, a second extractor's features taken from recorded corners (extract_from),
// and the all-pairs Hamming distance that brute-force matching pays.
// (BM_OrbExtract in slam_frontend_bench.cpp times the static room at 1000/2000 features.)
#include <benchmark/benchmark.h>

#include <optional>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/slam/orb_features.hpp"
#include "ds3d/slam/synth.hpp"

namespace {

const ds3d::synth::SynthFrame& frame() {
  static const ds3d::synth::SynthFrame f = [] {
    ds3d::synth::SynthOptions o;
    o.scenario = ds3d::synth::Scenario::kWalkingXyz;
    o.num_frames = 1;
    return ds3d::synth::SyntheticScene(o).render(0);
  }();
  return f;
}

// Args: num_features, num_levels, grey (1) or BGR (0) input.
void BM_OrbExtract(benchmark::State& state) {
  cv::setNumThreads(1);
  ds3d::slam::OrbParams p;
  p.num_features = static_cast<int>(state.range(0));
  p.num_levels = static_cast<int>(state.range(1));
  const ds3d::slam::OrbExtractor ex(p);
  cv::Mat image = frame().rgb;
  if (state.range(2) != 0) cv::cvtColor(frame().rgb, image, cv::COLOR_BGR2GRAY);
  const ds3d::PinholeCamera cam = ds3d::synth::SynthOptions{}.camera;
  std::size_t n = 0;
  for (auto _ : state) {
    auto r = ex.extract(image, frame().depth, cam);
    n = r.size();
    benchmark::DoNotOptimize(r);
  }
  state.counters["keypoints"] = static_cast<double>(n);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_OrbExtract)
    ->Args({500, 8, 0})
    ->Args({1000, 8, 0})
    ->Args({2000, 8, 0})
    ->Args({1000, 4, 0})
    ->Args({1000, 8, 1})
    ->Unit(benchmark::kMillisecond);

// The geometric source's 800 features taken from the front-end's recorded corners (1000
// features) with extract_from, against extracting them again (BM_OrbExtract/800 equivalent).
void BM_OrbExtractFrom(benchmark::State& state) {
  cv::setNumThreads(1);
  const ds3d::slam::OrbExtractor front;
  ds3d::slam::OrbParams p;
  p.num_features = static_cast<int>(state.range(0));
  const ds3d::slam::OrbExtractor source(p);
  const ds3d::PinholeCamera cam = ds3d::synth::SynthOptions{}.camera;
  ds3d::slam::OrbCorners corners;
  ds3d::slam::OrbFeatures spare;
  (void)front.extract(frame().rgb, frame().depth, cam, spare, 0, corners);
  std::size_t n = 0;
  for (auto _ : state) {
    auto f = state.range(1) != 0 ? source.extract_from(corners, frame().depth, cam)
                                 : std::optional(source.extract(frame().rgb, frame().depth, cam));
    n = f ? f->size() : 0;
    benchmark::DoNotOptimize(f);
  }
  state.counters["keypoints"] = static_cast<double>(n);
}
BENCHMARK(BM_OrbExtractFrom)
    ->ArgNames({"features", "from_corners"})
    ->Args({800, 0})
    ->Args({800, 1})
    ->Unit(benchmark::kMillisecond);

// N x N descriptor_distance between the features of two frames (N = 1000): brute matching cost.
void BM_DescriptorDistanceAllPairs(benchmark::State& state) {
  cv::setNumThreads(1);
  const ds3d::slam::OrbExtractor ex;
  const ds3d::PinholeCamera cam = ds3d::synth::SynthOptions{}.camera;
  const auto a = ex.extract(frame().rgb, frame().depth, cam);
  cv::Mat flipped;
  cv::flip(frame().rgb, flipped, 1);
  const auto b = ex.extract(flipped, cv::Mat(), cam);
  for (auto _ : state) {
    long sum = 0;
    for (int i = 0; i < a.descriptors.rows; ++i) {
      for (int j = 0; j < b.descriptors.rows; ++j) {
        sum += ds3d::slam::descriptor_distance(a.descriptors.ptr(i), b.descriptors.ptr(j));
      }
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * a.descriptors.rows * b.descriptors.rows);
}
BENCHMARK(BM_DescriptorDistanceAllPairs)->Unit(benchmark::kMillisecond);

}  // namespace
