// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Demo step 80: the HTx-lite 3-D detector with the shipped weights on a generated frame with
// walking people: boxes, part-head foreground points and timings.
#include <chrono>
#include <iostream>
#include <memory>
#include <vector>

#include "ds3d/htx/sparse_detector.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/slam/synth.hpp"
#include "ds3d_demo/demo.hpp"

namespace {

void htx_demo(const ds3d::demo::Context& ctx) {
  const auto weights = ds3d::slam::find_default_weights();
  auto det = std::make_shared<const ds3d::SparseDetector>(ds3d::SparseDetector::load(weights));
  ds3d::synth::SynthOptions o;
  o.scenario = ds3d::synth::Scenario::kWalkingStatic;
  o.num_frames = 20;
  o.seed = ctx.seed;
  const ds3d::synth::SyntheticScene scene(o);
  ds3d::slam::HtxSource source(det);
  const std::size_t frame = ctx.quick ? 2 : 10;
  std::size_t visible = 0;
  ds3d::slam::DynamicObjects objects;
  const auto t0 = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i <= frame; ++i) {  // the source keeps state across frames
    auto f = scene.render(i);
    ds3d::slam::FrameInput in;
    in.index = i;
    in.timestamp = f.timestamp;
    in.rgb = std::move(f.rgb);
    in.depth = std::move(f.depth);
    objects = source.detect(in, o.camera);
    if (i == frame) {
      for (const auto& b : f.boxes) visible += b.visible_pixels > 0 ? 1 : 0;
    }
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() /
      static_cast<double>(frame + 1);
  const auto& st = source.last_stats();
  std::cout << "HTx-lite '" << det->config().profile << "' (" << weights.filename().string()
            << ") on frame " << frame << " of walking_static: " << st.num_boxes << " person boxes ("
            << visible << " people in view), " << st.num_foreground << " of " << st.num_points
            << " points segmented as foreground; " << ms
            << " ms per frame (preprocess + network, 1 thread)\n";
  for (const auto& b : objects.boxes_3d) {
    const Eigen::Vector3f c = b.colwise().mean().transpose();
    std::cout << "  box at (" << c.x() << ", " << c.y() << ", " << c.z() << ") m, camera frame\n";
  }
}

}  // namespace

DS3D_DEMO_STEP(80, "HTx detector: the shipped weights on a generated frame", htx_demo);
