// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Synthetic generator: CPU time to render one 640x480 frame (target <= 50 ms on one core) per
// scenario, and to encode its PNGs. ProcessCPUTime: robust on a shared, loaded machine.
#include <benchmark/benchmark.h>

#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "ds3d/slam/synth.hpp"

namespace {

using ds3d::synth::Scenario;

void BM_RenderFrame(benchmark::State& state) {
  const auto scenario = static_cast<Scenario>(state.range(0));
  const ds3d::synth::SyntheticScene scene({.scenario = scenario,
                                           .num_frames = 300,
                                           .seed = 1,
                                           .num_humans = static_cast<int>(state.range(1))});
  std::size_t i = 0;
  for (auto _ : state) {
    auto f = scene.render(i);
    benchmark::DoNotOptimize(f.rgb.data);
    i = (i + 37) % scene.size();
  }
  state.SetLabel(ds3d::synth::scenario_name(scenario) + ", humans " +
                 std::to_string(state.range(1)));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_RenderFrame)
    ->ArgsProduct({{static_cast<int>(Scenario::kStaticRoom),
                    static_cast<int>(Scenario::kWalkingXyz),
                    static_cast<int>(Scenario::kSittingStatic)},
                   {0, 2, 4}})
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

void BM_EncodePngs(benchmark::State& state) {
  const ds3d::synth::SyntheticScene scene({.num_frames = 1});
  const auto f = scene.render(0);
  std::vector<std::uint8_t> buf;
  for (auto _ : state) {
    cv::imencode(".png", f.rgb, buf,
                 {cv::IMWRITE_PNG_COMPRESSION, 1, cv::IMWRITE_PNG_STRATEGY,
                  cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY});
    cv::imencode(".png", f.depth, buf,
                 {cv::IMWRITE_PNG_COMPRESSION, 1, cv::IMWRITE_PNG_STRATEGY,
                  cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY});
    cv::imencode(".png", f.dynamic_mask, buf,
                 {cv::IMWRITE_PNG_COMPRESSION, 1, cv::IMWRITE_PNG_STRATEGY,
                  cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY});
    benchmark::DoNotOptimize(buf.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_EncodePngs)->MeasureProcessCPUTime()->Unit(benchmark::kMillisecond);

}  // namespace
