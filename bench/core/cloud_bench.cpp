// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Cost of reading points through PointCloudTraits for the shipped adaptors: it should be the
// same as a raw loop (the traits are meant to be zero-overhead).
#include <benchmark/benchmark.h>

#include <vector>

#include "ds3d/cloud.hpp"
#include "support/synthetic.hpp"

namespace {

template <class C>
C make(std::size_t n);
template <>
ds3d::Points3f make(std::size_t n) {
  ds3d::test::Rng rng(1);
  return ds3d::test::uniform_box(n, {-1, -1, -1}, {1, 1, 1}, rng);
}
template <>
std::vector<Eigen::Vector3f> make(std::size_t n) {
  const ds3d::Points3f p = make<ds3d::Points3f>(n);
  std::vector<Eigen::Vector3f> v;
  for (Eigen::Index i = 0; i < p.rows(); ++i) v.emplace_back(p.row(i).transpose());
  return v;
}

template <class C>
void BM_TraitsSum(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const C c = make<C>(n);
  for (auto _ : state) {
    Eigen::Vector3f s = Eigen::Vector3f::Zero();
    for (std::size_t i = 0; i < ds3d::cloud::size(c); ++i) s += ds3d::cloud::point(c, i);
    benchmark::DoNotOptimize(s);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
}
BENCHMARK_TEMPLATE(BM_TraitsSum, ds3d::Points3f)->Arg(10'000)->Arg(300'000);
BENCHMARK_TEMPLATE(BM_TraitsSum, std::vector<Eigen::Vector3f>)->Arg(10'000)->Arg(300'000);

}  // namespace
