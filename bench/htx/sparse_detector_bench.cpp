// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HTx-lite inference time per frame (network + post-processing; the part head separately),
// fast and quality profiles, 4,096 gravity-aligned points, 1 or 2 threads. Weights are random
// (timing does not depend on their values). Compare with PyTorch: scripts/bench_htx_vs_torch.py.
// BM_HtxFrame: one whole `--dynamic htx` detection (HtxSource::detect: preprocess of a 640x480
// synthetic depth frame, gravity alignment, the 4,096-point draw, the network, box conversion).
#include <benchmark/benchmark.h>

#include <memory>
#include <string>
#include <vector>

#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/htx/sparse_detector.hpp"
#include "ds3d/slam/synth.hpp"
#include "ds3d/htx/weights_io.hpp"
#include "support/htx_random.hpp"

namespace {

const ds3d::SparseDetector& detector(int profile) {
  static const ds3d::SparseDetector fast =
      ds3d::SparseDetector::from_weights(ds3d::WeightsFile::parse(
          ds3d::test::random_htx_file(ds3d::DetectorConfig::make_profile("fast"), 1)));
  static const ds3d::SparseDetector quality =
      ds3d::SparseDetector::from_weights(ds3d::WeightsFile::parse(
          ds3d::test::random_htx_file(ds3d::DetectorConfig::make_profile("quality"), 1)));
  return profile == 0 ? fast : quality;
}

// Args: profile (0 fast, 1 quality), threads, part head (0/1).
void BM_HtxDetect(benchmark::State& state) {
  const auto& det = detector(static_cast<int>(state.range(0)));
  const auto pts = ds3d::test::htx_scene(4096, 7);
  const ds3d::DetectOptions opt{.num_threads = static_cast<int>(state.range(1)),
                                .part_logits = state.range(2) != 0};
  for (auto _ : state) {
    auto out = det.run(pts, opt);
    benchmark::DoNotOptimize(out.proposals.data());
  }
  state.SetLabel(det.config().profile + (opt.part_logits ? "+parts" : ""));
  state.SetItemsProcessed(state.iterations() * pts.rows());
}
BENCHMARK(BM_HtxDetect)
    ->ArgNames({"profile", "threads", "parts"})
    ->ArgsProduct({{0, 1}, {1, 2}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);

// The synthetic frames of the BM_HtxFrame benchmarks (8 frames, two walkers, seed 3).
std::vector<ds3d::slam::FrameInput> htx_frames(ds3d::synth::SynthOptions& so) {
  so.num_frames = 8;
  so.seed = 3;
  so.num_humans = 2;
  const ds3d::synth::SyntheticScene scene(so);
  std::vector<ds3d::slam::FrameInput> frames;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const auto f = scene.render(i);
    ds3d::slam::FrameInput in;
    in.index = f.index;
    in.timestamp = f.timestamp;
    in.rgb = f.rgb;
    in.depth = f.depth;
    frames.push_back(in);
  }
  return frames;
}

// Args: profile (0 fast, 1 quality), segment (HtxSourceParams::segment: the part head runs on
// every point and the foreground is gathered). One thread. Counters: preprocess_ms / detect_ms
// (wall, mean per frame) and the preprocessed cloud size.
void BM_HtxFrame(benchmark::State& state) {
  ds3d::synth::SynthOptions so;
  const std::vector<ds3d::slam::FrameInput> frames = htx_frames(so);
  auto det =
      std::make_shared<const ds3d::SparseDetector>(detector(static_cast<int>(state.range(0))));
  ds3d::slam::HtxSource src(det, {.classes = {}, .segment = state.range(1) != 0});
  double pre_ms = 0;
  double det_ms = 0;
  double points = 0;
  std::size_t i = 0;
  for (auto _ : state) {
    auto out = src.detect(frames[i++ % frames.size()], so.camera);
    benchmark::DoNotOptimize(out.boxes_3d.data());
    pre_ms += src.last_stats().preprocess_ms;
    det_ms += src.last_stats().detect_ms;
    points += static_cast<double>(src.last_stats().num_points);
  }
  const auto n = static_cast<double>(state.iterations());
  state.counters["preprocess_ms"] = pre_ms / n;
  state.counters["detect_ms"] = det_ms / n;
  state.counters["cloud_points"] = points / n;
  state.SetLabel(det->config().profile + (state.range(1) != 0 ? "+segment" : ""));
}
BENCHMARK(BM_HtxFrame)
    ->ArgNames({"profile", "segment"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);

// The part-head averages, fast profile, segment on: Arg 0 the defaults (segment_frames 10),
// 1 segment_frames 0 (no frame average). Timestamps advance
// 1/30 s per iteration so the smoothing window stays full. Counter detect_ms as BM_HtxFrame.
void BM_HtxFrameAveraged(benchmark::State& state) {
  ds3d::synth::SynthOptions so;
  const std::vector<ds3d::slam::FrameInput> frames = htx_frames(so);
  auto det = std::make_shared<const ds3d::SparseDetector>(detector(0));
  ds3d::slam::HtxSourceParams p{.classes = {}};
  if (state.range(0) == 1) p.segment_frames = 0;
  ds3d::slam::HtxSource src(det, p);
  double det_ms = 0;
  std::size_t i = 0;
  for (auto _ : state) {
    ds3d::slam::FrameInput in = frames[i % frames.size()];
    in.index = i;
    in.timestamp = static_cast<double>(i) / 30.0;
    ++i;
    auto out = src.detect(in, so.camera);
    benchmark::DoNotOptimize(out.boxes_3d.data());
    det_ms += src.last_stats().detect_ms;
  }
  state.counters["detect_ms"] = det_ms / static_cast<double>(state.iterations());
}
BENCHMARK(BM_HtxFrameAveraged)->DenseRange(0, 1)->Unit(benchmark::kMillisecond)->MinTime(1.0);

}  // namespace
