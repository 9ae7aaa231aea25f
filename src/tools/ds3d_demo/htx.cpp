// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Demo step 80: the HTx-lite detector with random weights (no trained weights exist yet): writes a
// weights file, loads it, detects on a synthetic gravity-aligned room and computes Part-A2 targets.
#include <chrono>
#include <fstream>
#include <iostream>
#include <random>
#include <vector>

#include "ds3d/htx/part_a2_targets.hpp"
#include "ds3d/htx/sparse_detector.hpp"
#include "ds3d/htx/weights_io.hpp"
#include "ds3d_demo/demo.hpp"

namespace {

void htx_demo(const ds3d::demo::Context& ctx) {
  const auto config = ds3d::DetectorConfig::make_profile("fast");
  std::mt19937 gen(static_cast<std::mt19937::result_type>(ctx.seed));
  std::vector<ds3d::NamedTensor> tensors;
  for (const auto& [name, shape] : ds3d::SparseDetector::expected_tensors(config)) {
    std::int64_t n = 1;
    for (const auto s : shape) n *= s;
    const float bound = shape.size() == 2 ? 1.0F / std::sqrt(static_cast<float>(shape[1])) : 0.1F;
    std::uniform_real_distribution<float> u(-bound, bound);
    ds3d::NamedTensor t{name, shape, std::vector<float>(static_cast<std::size_t>(n))};
    const bool gain = name.find("norm") != std::string::npos && name.ends_with(".weight");
    for (auto& v : t.data) v = gain ? 1.0F + u(gen) : u(gen);
    tensors.push_back(std::move(t));
  }
  const auto path = ctx.out_dir / "htx_fast_random.safetensors";
  {
    std::ofstream f(path, std::ios::binary);
    f << ds3d::serialize_safetensors(
        tensors, {{"format", "ds3d-htx"}, {"version", "1"}, {"config", config.to_json()}});
  }
  const auto det = ds3d::SparseDetector::load(path);
  // A room: back wall, a table and a person-sized column, 4,096 points, Z up.
  const std::size_t n = ctx.quick ? 1024 : 4096;
  ds3d::Points3f pts(static_cast<Eigen::Index>(n), 3);
  std::uniform_real_distribution<float> u01(0.0F, 1.0F);
  const float lo[3][3] = {{-2.0F, 3.9F, 0.0F}, {-1.0F, 2.5F, 0.0F}, {0.2F, 1.5F, 0.0F}};
  const float hi[3][3] = {{2.0F, 4.0F, 2.5F}, {0.0F, 3.2F, 0.8F}, {0.7F, 2.0F, 1.7F}};
  for (Eigen::Index i = 0; i < pts.rows(); ++i) {
    const auto k = static_cast<std::size_t>(i % 3);
    for (int a = 0; a < 3; ++a) pts(i, a) = lo[k][a] + (hi[k][a] - lo[k][a]) * u01(gen);
  }
  const auto t0 = std::chrono::steady_clock::now();
  const auto out = det.run(pts, {.num_threads = 1, .part_logits = true});
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "HTx-lite '" << det.config().profile << "': " << det.config().num_centres
            << " tokens, " << out.proposals.size() << " queries -> " << out.boxes.size()
            << " boxes after NMS in " << ms << " ms (1 thread, random weights)\n";
  ds3d::Box3 person;
  person.centre = {0.45F, 1.75F, 0.85F};
  person.size = {0.5F, 0.5F, 1.7F};
  const auto targets = ds3d::part_a2_targets(pts, std::vector<ds3d::Box3>{person});
  std::size_t fg = 0, ignore = 0;
  for (const auto l : targets.label) {
    fg += l == 1;
    ignore += l == -1;
  }
  std::cout << "Part-A2 targets for a person box: " << fg << " foreground, " << ignore
            << " ignored points; weights in " << path.string() << "\n";
}

}  // namespace

DS3D_DEMO_STEP(80, "HTx detector: random weights, detect, part targets", htx_demo);
