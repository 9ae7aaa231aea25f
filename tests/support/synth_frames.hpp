// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Every frame of a generated sequence (ds3d::synth), for SLAM-side tests and benchmarks.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "ds3d/slam/synth.hpp"

namespace ds3d::test {

/// Renders all `frames` frames of `scenario` (seed `seed`, the generator's other defaults), or only
/// the first `first_only` of them (> 0) of the same `frames`-frame sequence.
inline std::vector<synth::SynthFrame> render_sequence(synth::Scenario scenario, int frames,
                                                      std::uint64_t seed = 1,
                                                      std::size_t first_only = 0) {
  synth::SynthOptions o;
  o.scenario = scenario;
  o.num_frames = frames;
  o.seed = seed;
  const synth::SyntheticScene scene(o);
  const std::size_t n = first_only > 0 ? std::min(first_only, scene.size()) : scene.size();
  std::vector<synth::SynthFrame> out;
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) out.push_back(scene.render(i));
  return out;
}

}  // namespace ds3d::test
