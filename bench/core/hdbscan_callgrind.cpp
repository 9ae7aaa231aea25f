// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// One ds3d::hdbscan call on the benchmark data, for instruction counts that do not depend on the
// machine load (not a Google Benchmark target; build and run commands in docs/hdbscan.md).
// Usage: hdbscan_callgrind kp|blobs N [algo 0=auto 1=prims 2=boruvka] [reps]. Prints a hash of
// the labels and MST weights so that two builds can be checked for bitwise-identical results;
// with reps > 0 it also times that many further calls and prints the median thread CPU time
// (for same-run ratios of two builds on a loaded machine).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <vector>

#include "ds3d/cluster/hdbscan.hpp"
#include "support/keypoints.hpp"
#include "support/synthetic.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s kp|blobs N [algo]\n", argv[0]);
    return 2;
  }
  const std::size_t n = std::strtoul(argv[2], nullptr, 10);
  const int algo = argc > 3 ? std::atoi(argv[3]) : 0;
  const ds3d::RowMatrixXd x =
      std::strcmp(argv[1], "kp") == 0
          ? ds3d::RowMatrixXd(ds3d::test::person_keypoints(n, 42))
          : ds3d::RowMatrixXd(ds3d::test::gaussian_blobs(n, 3, 10, 0.2, 7, 10.0, 1.0).x);
  ds3d::HdbscanParams p;  // as bench/core/hdbscan_bench.cpp
  p.min_cluster_size = 15;
  p.min_samples = 10;
  p.algorithm = static_cast<ds3d::MstAlgorithm>(algo);
  const auto r = ds3d::hdbscan(x, p);
  std::uint64_t h = 0;
  for (const auto l : r.labels) h = h * 1000003U + static_cast<std::uint64_t>(l + 1);
  for (const auto& e : r.min_spanning_tree) {
    std::uint64_t b = 0;
    std::memcpy(&b, &e.weight, sizeof b);
    h = h * 31U + b;
  }
  // Full hash: also MST endpoints, core distances, probabilities and outlier scores (bit
  // patterns, so NaN and -0.0 count), for checks that a change is bitwise neutral everywhere.
  std::uint64_t f = h;
  auto mix = [&f](double v) {
    std::uint64_t b = 0;
    std::memcpy(&b, &v, sizeof b);
    f = f * 1099511628211ULL + b;
  };
  for (const auto& e : r.min_spanning_tree)
    f = f * 1099511628211ULL + (std::uint64_t{e.from} << 32U | e.to);
  for (const double v : r.core_distances) mix(v);
  for (const double v : r.probabilities) mix(v);
  for (const double v : r.outlier_scores) mix(v);
  for (const double v : r.cluster_persistence) mix(v);
  std::printf("clusters %d hash %llx full %llx\n", r.num_clusters,
              static_cast<unsigned long long>(h), static_cast<unsigned long long>(f));
  const int reps = argc > 4 ? std::atoi(argv[4]) : 0;
  if (reps > 0) {
    auto cpu_ms = [] {
      timespec ts{};
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
      return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
    };
    std::vector<double> t;
    for (int i = 0; i < reps; ++i) {
      const double t0 = cpu_ms();
      const auto ri = ds3d::hdbscan(x, p);
      t.push_back(cpu_ms() - t0);
      if (ri.labels.size() != r.labels.size()) return 1;
    }
    std::sort(t.begin(), t.end());
    std::printf("median CPU %.3f ms over %d calls\n", t[t.size() / 2], reps);
  }
  return 0;
}
