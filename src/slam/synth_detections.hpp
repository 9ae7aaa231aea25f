// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Detector errors for detections_noisy.jsonl (used by generate_sequence). Not API.

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "synth_impl.hpp"

namespace ds3d::synth {

// Builds detections_noisy.jsonl frame by frame, in order: the true person boxes (3-D corners in
// the camera frame, score 0.9) of the people with enough visible pixels, each dropped in runs
// (a two-state chain per person whose stationary miss probability is detection_miss), and with
// probability detection_false a false person box (score 0.6) on a static surface of the frame.
class NoisyDetections {
 public:
  explicit NoisyDetections(const SynthOptions& opt);
  void add(const SynthFrame& f, const std::string& stamp);
  [[nodiscard]] const std::string& text() const { return text_; }
  // A person with fewer visible pixels is not detectable at all (0.2 % of the image, >= 20).
  [[nodiscard]] static int min_visible_pixels(const PinholeCamera& camera);

 private:
  double miss_;
  double false_;
  PinholeCamera camera_;
  std::mt19937_64 rng_;
  std::vector<bool> missed_;
  std::string text_;
};

}  // namespace ds3d::synth
