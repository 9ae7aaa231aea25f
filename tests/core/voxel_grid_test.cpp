// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d::voxel_grid against the golden fixtures, a brute-force reference and edge cases.
#include "ds3d/preprocess/voxel_grid.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "ds3d/preprocess/rgbd.hpp"
#include "support/depth_scene.hpp"
#include "support/preprocess_fixtures.hpp"
#include "support/synthetic.hpp"

namespace {

using ds3d::Points3f;
using ds3d::VoxelGridParams;
using ds3d::VoxelGridResult;

/// Leaf sizes of a case.json voxel output entry.
ds3d::LeafSize leaf_of(const ds3d::detail::JsonValue& out) {
  const auto& s = out.at("voxel_size");
  return {s.at(0).as_number(), s.at(1).as_number(), s.at(2).as_number()};
}

void expect_matches_golden(const VoxelGridResult& r, const std::vector<ds3d::test::GoldenVoxel>& g,
                           const std::string& what) {
  ASSERT_EQ(static_cast<std::size_t>(r.centroids.rows()), g.size()) << what;
  ASSERT_TRUE(r.centroids.allFinite()) << what;
  for (std::size_t i = 0; i < g.size(); ++i) {
    const auto row = static_cast<Eigen::Index>(i);
    ASSERT_EQ(r.keys(row, 0), g[i].key[0]) << what << " row " << i;
    ASSERT_EQ(r.keys(row, 1), g[i].key[1]) << what << " row " << i;
    ASSERT_EQ(r.keys(row, 2), g[i].key[2]) << what << " row " << i;
    ASSERT_EQ(r.counts[i], g[i].count) << what << " row " << i;
    for (int d = 0; d < 3; ++d) {
      const double gold = g[i].centroid[static_cast<std::size_t>(d)];
      EXPECT_LE(std::abs(static_cast<double>(r.centroids(row, d)) - gold),
                1e-5 + 1e-6 * std::abs(gold))
          << what << " row " << i << " axis " << d;
    }
  }
}

TEST(VoxelGrid, MatchesEveryGoldenFixture) {
  int checked = 0;
  for (const auto& root : ds3d::test::preprocess_fixture_roots()) {
    for (const auto& dir : ds3d::test::preprocess_cases(root)) {
      const auto meta = ds3d::test::read_json(dir / "case.json");
      const Points3f pts = ds3d::test::read_points_bin(dir / "input.bin");
      ASSERT_EQ(pts.rows(), meta.at("n_points").as_int());
      for (const auto& out : meta.at("outputs").at("voxel").as_array()) {
        const auto file = dir / out.at("file").as_string();
        if (!std::filesystem::exists(file)) continue;  // trimmed from the in-repo copy
        for (const int threads : {1, 3}) {
          VoxelGridParams p;
          p.leaf_size = leaf_of(out);
          p.num_threads = threads;
          p.parallel_min_points = 0;  // threads even on small clouds: test the parallel passes
          const VoxelGridResult r = ds3d::voxel_grid(pts, p);
          expect_matches_golden(r, ds3d::test::read_voxel_csv(file), file.string());
          EXPECT_EQ(r.num_non_finite, static_cast<std::size_t>(meta.at("n_points").as_int() -
                                                               meta.at("n_finite").as_int()));
          // Representatives are members of their voxel.
          for (std::size_t i = 0; i < r.representative.size(); ++i) {
            const auto q = pts.row(r.representative[i]);
            EXPECT_EQ(static_cast<std::int64_t>(std::floor(double(q.x()) / p.leaf_size.dx)),
                      r.keys(static_cast<Eigen::Index>(i), 0));
          }
        }
        ++checked;
      }
    }
  }
  EXPECT_GE(checked, 15);  // the in-repo copy alone has 15 voxel outputs
}

TEST(VoxelGrid, EmptyInput) {
  const Points3f none(0, 3);
  const auto r = ds3d::voxel_grid(none);
  EXPECT_EQ(r.centroids.rows(), 0);
  EXPECT_EQ(r.keys.rows(), 0);
  EXPECT_TRUE(r.counts.empty());
  EXPECT_TRUE(r.representative.empty());
}

TEST(VoxelGrid, OnePoint) {
  Points3f p(1, 3);
  p << -0.01F, 0.26F, 1.0F;
  const auto r = ds3d::voxel_grid(p, {.leaf_size = 0.25});
  ASSERT_EQ(r.centroids.rows(), 1);
  EXPECT_EQ(r.keys(0, 0), -1);
  EXPECT_EQ(r.keys(0, 1), 1);
  EXPECT_EQ(r.keys(0, 2), 4);
  EXPECT_EQ(r.counts[0], 1U);
  EXPECT_EQ(r.representative[0], 0U);
  EXPECT_EQ(r.centroids.row(0), p.row(0));
}

TEST(VoxelGrid, AllPointsInOneVoxelAndExactDuplicates) {
  ds3d::test::Rng rng(5);
  Points3f p = ds3d::test::uniform_box(500, {0.1, 0.1, 0.1}, {0.9, 0.9, 0.9}, rng);
  for (Eigen::Index i = 0; i < 100; ++i) p.row(400 + i) = p.row(7);  // exact duplicates
  const auto r = ds3d::voxel_grid(p, {.leaf_size = 1.0});
  ASSERT_EQ(r.centroids.rows(), 1);
  EXPECT_EQ(r.counts[0], 500U);
  const Eigen::Vector3d mean = p.cast<double>().colwise().mean();
  EXPECT_NEAR(r.centroids(0, 0), mean.x(), 1e-6);
  EXPECT_NEAR(r.centroids(0, 1), mean.y(), 1e-6);
  EXPECT_NEAR(r.centroids(0, 2), mean.z(), 1e-6);
  // Representative: the member nearest the centroid.
  double best = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    best = std::min(best, (p.row(i).cast<double>() - mean.transpose()).squaredNorm());
  }
  EXPECT_NEAR((p.row(r.representative[0]).cast<double>() - mean.transpose()).squaredNorm(), best,
              1e-9);
}

TEST(VoxelGrid, MatchesBruteForce) {
  ds3d::test::Rng rng(11);
  const Points3f p = ds3d::test::uniform_box(20'000, {-3, -2, -0.5}, {2, 3, 4.5}, rng);
  const ds3d::LeafSize leaf(0.13, 0.2, 0.07);
  std::map<std::array<std::int64_t, 3>, std::pair<Eigen::Vector3d, std::uint32_t>> ref;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const std::array<std::int64_t, 3> k{
        static_cast<std::int64_t>(std::floor(double(p(i, 0)) / leaf.dx)),
        static_cast<std::int64_t>(std::floor(double(p(i, 1)) / leaf.dy)),
        static_cast<std::int64_t>(std::floor(double(p(i, 2)) / leaf.dz))};
    auto& e = ref[k];
    if (e.second == 0) e.first.setZero();
    e.first += p.row(i).transpose().cast<double>();
    ++e.second;
  }
  const auto r = ds3d::voxel_grid(p, {.leaf_size = leaf});
  ASSERT_EQ(static_cast<std::size_t>(r.centroids.rows()), ref.size());
  std::size_t i = 0;
  for (const auto& [k, e] : ref) {
    const auto row = static_cast<Eigen::Index>(i++);
    ASSERT_EQ(r.keys(row, 0), k[0]);
    ASSERT_EQ(r.keys(row, 1), k[1]);
    ASSERT_EQ(r.keys(row, 2), k[2]);
    ASSERT_EQ(r.counts[static_cast<std::size_t>(row)], e.second);
    const Eigen::Vector3d mean = e.first / e.second;
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(r.centroids(row, d), mean[d], 1e-6);
  }
}

/// The definition, coded the slow way: keys floor(double(v) / leaf) in an ordered map, members in
/// input order, mean = sum * (1 / count) in double, representative = first nearest member.
VoxelGridResult brute_force_voxels(const Points3f& p, const ds3d::LeafSize& leaf) {
  std::map<std::array<std::int64_t, 3>, std::vector<std::uint32_t>> cells;
  VoxelGridResult r;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    if (!p.row(i).allFinite()) {
      ++r.num_non_finite;
      continue;
    }
    cells[{static_cast<std::int64_t>(std::floor(double(p(i, 0)) / leaf.dx)),
           static_cast<std::int64_t>(std::floor(double(p(i, 1)) / leaf.dy)),
           static_cast<std::int64_t>(std::floor(double(p(i, 2)) / leaf.dz))}]
        .push_back(static_cast<std::uint32_t>(i));
  }
  const auto m = static_cast<Eigen::Index>(cells.size());
  r.centroids.resize(m, 3);
  r.keys.resize(m, 3);
  Eigen::Index row = 0;
  for (const auto& [k, members] : cells) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto i : members) sum += p.row(i).transpose().cast<double>();
    const Eigen::Vector3d mean = sum * (1.0 / static_cast<double>(members.size()));
    double best_d = std::numeric_limits<double>::infinity();
    std::uint32_t best = members[0];
    for (const auto i : members) {
      const double d = (p.row(i).transpose().cast<double>() - mean).squaredNorm();
      if (d < best_d) {
        best_d = d;
        best = i;
      }
    }
    r.keys.row(row) << k[0], k[1], k[2];
    r.centroids.row(row) = mean.cast<float>().transpose();
    r.counts.push_back(static_cast<std::uint32_t>(members.size()));
    r.representative.push_back(best);
    ++row;
  }
  return r;
}

void expect_same(const VoxelGridResult& r, const VoxelGridResult& ref, const std::string& what) {
  ASSERT_EQ(r.keys.rows(), ref.keys.rows()) << what;
  EXPECT_EQ(r.keys, ref.keys) << what;
  EXPECT_EQ(r.counts, ref.counts) << what;
  EXPECT_EQ(r.centroids, ref.centroids) << what;  // same sums in the same order: bit-identical
  EXPECT_EQ(r.representative, ref.representative) << what;
  EXPECT_EQ(r.num_non_finite, ref.num_non_finite) << what;
}

/// Coordinates on voxel boundaries k * leaf (rounded to float) and one float ulp either side, -0.0
/// and ±denormals, mixed with random ones: the vectorised key loop must hand every doubtful one
/// to the exact path. (With leaf 0.07, x * (1 / leaf) and x / leaf floor differently for
/// thousands of such values, e.g. x = 1.75.)
Points3f boundary_cloud(std::size_t n, double leaf, double extent, ds3d::test::Rng& rng) {
  Points3f p(static_cast<Eigen::Index>(n), 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    for (int d = 0; d < 3; ++d) {
      const double u = rng.uniform(-extent, extent);
      float v = static_cast<float>(u);
      const auto kind = rng.next() % 5;
      if (kind != 0) v = static_cast<float>(std::round(u / leaf) * leaf);
      if (kind == 4) v = std::array<float, 3>{-0.0F, 1.4e-45F, -1.4e-45F}[rng.next() % 3];
      if (kind == 2) v = std::nextafter(v, std::numeric_limits<float>::infinity());
      if (kind == 3) v = std::nextafter(v, -std::numeric_limits<float>::infinity());
      p(i, d) = v;
    }
  }
  return p;
}

TEST(VoxelGrid, VectorisedKeysMatchBruteForceOnBoundaries) {
  ds3d::test::Rng rng(21);
  // Sizes around the 4-point SIMD step and the 256-point block (tails of every length).
  for (const std::size_t n : {1, 3, 4, 5, 255, 256, 257, 517, 3001}) {
    for (const double leaf : {0.01, 0.05, 0.07, 0.1, 0.125, 0.3}) {
      const Points3f p = boundary_cloud(n, leaf, 40 * leaf, rng);
      const std::string what = "n " + std::to_string(n) + " leaf " + std::to_string(leaf);
      expect_same(ds3d::voxel_grid(p, {.leaf_size = leaf}), brute_force_voxels(p, leaf), what);
      expect_same(
          ds3d::voxel_grid(p, {.leaf_size = leaf, .num_threads = 3, .parallel_min_points = 0}),
          brute_force_voxels(p, leaf), what + " 3 threads");
    }
  }
}

TEST(VoxelGrid, KeyBoundsWithNonFiniteBlocks) {
  // The key bounds come from float min/max for blocks without non-finite points and from the
  // keys for the others; put each axis extreme in a block that holds a NaN or an inf.
  ds3d::test::Rng rng(8);
  Points3f p = ds3d::test::uniform_box(2000, {-1, -1, -1}, {1, 1, 1}, rng);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  p.row(10) << nan, 0, 0;
  p.row(11) << -5, -6, -7;  // minima, same block as the NaN
  p.row(600) << 0, -inf, 0;
  p.row(601) << 5, 6, 7;  // maxima, same block as the inf
  p.row(1999) << nan, nan, nan;
  const ds3d::LeafSize leaf(0.03, 0.05, 0.07);
  expect_same(ds3d::voxel_grid(p, {.leaf_size = leaf}), brute_force_voxels(p, leaf), "1 thread");
  expect_same(ds3d::voxel_grid(p, {.leaf_size = leaf, .num_threads = 2, .parallel_min_points = 0}),
              brute_force_voxels(p, leaf), "2 threads");
}

TEST(VoxelGrid, EveryKeyWidthPathMatchesBruteForce) {
  ds3d::test::Rng rng(9);
  // (leaf, box): packed key <= 32 bits (radix on (key, index) pairs); 39 bits (64-bit keys);
  // fields beyond ±2^20 but a 42-bit range (int64 triples packed in 64 bits); a 105-bit range
  // (comparison sort).
  struct Case {
    double leaf;
    double lo;
    double hi;
  };
  for (const Case& c :
       {Case{0.05, -3, 3}, Case{0.001, -4, 4}, Case{1e-4, 200, 201}, Case{1e-7, -1e3, 1e3}}) {
    const Points3f p = ds3d::test::uniform_box(4000, {c.lo, c.lo, c.lo}, {c.hi, c.hi, c.hi}, rng);
    const std::string what = "leaf " + std::to_string(c.leaf);
    for (const int t : {1, 2}) {
      expect_same(
          ds3d::voxel_grid(p, {.leaf_size = c.leaf, .num_threads = t, .parallel_min_points = 0}),
          brute_force_voxels(p, c.leaf), what + " threads " + std::to_string(t));
    }
  }
}

TEST(VoxelGrid, DenseAndSparseBoxesMatchBruteForce) {
  // The same cloud at a coarse leaf (a key box of <= 16 cells per point: occupancy bitmap, no
  // sort) and a fine one (pair radix sort), with non-finite points, on 1 and 3 threads.
  ds3d::test::Rng rng(17);
  Points3f p = ds3d::test::uniform_box(6000, {-0.7F, 0.2F, 1.0F}, {0.9F, 1.1F, 2.5F}, rng);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const Eigen::Index i : {0, 7, 255, 256, 3001, 5999}) p(i, i % 3) = nan;
  p.row(100) << std::numeric_limits<float>::infinity(), 0, 0;
  for (Eigen::Index i = 4000; i < 4100; ++i) p.row(i) = p.row(i - 900);  // exact duplicates
  for (const double leaf : {0.2, 0.05, 0.011}) {
    const std::size_t cells =
        static_cast<std::size_t>((1.6 / leaf + 2) * (0.9 / leaf + 2) * (1.5 / leaf + 2));
    const std::string what = "leaf " + std::to_string(leaf) + " (" + std::to_string(cells) +
                             " cells, " + (cells <= 16 * 6000 ? "dense" : "sparse") + ")";
    const VoxelGridResult ref = brute_force_voxels(p, leaf);
    EXPECT_EQ(ref.num_non_finite, 7U);
    for (const int t : {1, 3}) {
      expect_same(
          ds3d::voxel_grid(p, {.leaf_size = leaf, .num_threads = t, .parallel_min_points = 0}), ref,
          what + " threads " + std::to_string(t));
    }
  }
}

TEST(VoxelGrid, SparseRowBlocksAndFieldWidthsMatchBruteForce) {
  // The sparse path builds its rows per block of 256 sorted pairs: voxels whose members span
  // one or more block boundaries (255, 256, 257 and 700 members), a key with no x bits (the
  // decoder's x shift is then the full 64 bits) and a 32-bit key with non-finite points.
  ds3d::test::Rng rng(31);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Points3f runs = ds3d::test::uniform_box(3000, {0, 0, 0}, {1, 1, 1}, rng);
  for (const int members : {255, 256, 257, 700}) {
    Points3f more(members, 3);
    const float c = 0.1F * static_cast<float>(members % 9) + 0.0031F;
    for (Eigen::Index i = 0; i < more.rows(); ++i) {
      more.row(i) << c + static_cast<float>(rng.uniform(0, 0.005)),
          c + static_cast<float>(rng.uniform(0, 0.005)), 0.5031F;
    }
    Points3f both(runs.rows() + more.rows(), 3);
    both << runs, more;
    runs = both;
  }
  Points3f flat_x = ds3d::test::uniform_box(5000, {0.123F, 0, 0}, {0.123F, 20, 20}, rng);
  Points3f wide = ds3d::test::uniform_box(5000, {0, 0, 0}, {20, 20, 5}, rng);
  for (const Eigen::Index i : {3, 256, 4999}) wide(i, i % 3) = nan;
  for (const auto& [name, cloud] : {std::pair<std::string, const Points3f&>{"runs", runs},
                                    {"no x bits", flat_x},
                                    {"32-bit keys", wide}}) {
    const VoxelGridResult ref = brute_force_voxels(cloud, 0.01);
    for (const int t : {1, 3}) {
      expect_same(
          ds3d::voxel_grid(cloud, {.leaf_size = 0.01, .num_threads = t, .parallel_min_points = 0}),
          ref, name + " threads " + std::to_string(t));
    }
  }
}

TEST(VoxelGrid, SensorOrderAndShuffledTwoDigitSortMatchBruteForce) {
  // A rendered depth frame (row-major, as a sensor delivers it) with a fine x leaf: keys of 23 to
  // 32 bits whose (y, z) fields fit in log2(n) bits take the one-thread (y, z) / x split of the
  // radix sort (on 1 and 3 threads), in two passes for the sensor order and in three (the
  // fallback for arbitrary orders) once shuffled; non-finite points (the extra key bit),
  // duplicates, min_points and a reused workspace included, checked against the brute force and the
  // 3-thread result.
  ds3d::PinholeCamera cam;
  cam.width = 320;
  cam.height = 240;
  cam.fx = cam.fy = 262.5;
  cam.cx = 159.5;
  cam.cy = 119.5;
  const auto frame = ds3d::test::render_room(3, cam);
  Points3f sensor =
      ds3d::depth_to_points(frame.depth.data(), cam.width, cam.height, cam.width, cam).points;
  const ds3d::LeafSize leaf(0.006, 0.04, 0.04);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (Eigen::Index i = 5; i < sensor.rows(); i += 997) sensor(i, i % 3) = nan;
  for (Eigen::Index i = 1000; i < 1300; ++i) sensor.row(i) = sensor.row(i - 1);
  // The cloud must be one that the split applies to (see voxel_grid_sorted).
  std::array<double, 3> lo{1e30, 1e30, 1e30};
  std::array<double, 3> hi{-1e30, -1e30, -1e30};
  const std::array<double, 3> l{leaf.dx, leaf.dy, leaf.dz};
  for (Eigen::Index i = 0; i < sensor.rows(); ++i) {
    if (!sensor.row(i).allFinite()) continue;
    for (std::size_t d = 0; d < 3; ++d) {
      const double k = std::floor(double(sensor(i, static_cast<Eigen::Index>(d))) / l[d]);
      lo[d] = std::min(lo[d], k);
      hi[d] = std::max(hi[d], k);
    }
  }
  auto bits = [&](std::size_t d) {
    return static_cast<int>(std::bit_width(std::uint64_t(hi[d] - lo[d])));
  };
  const int key_bits = bits(0) + bits(1) + bits(2) + 1;  // + 1: non-finite points
  ASSERT_GE(key_bits, 23);
  ASSERT_LE(key_bits - bits(1) - bits(2), 11);
  // ... also on 3 threads (one joint histogram per thread).
  ASSERT_LE(std::uint64_t{3} << (bits(1) + bits(2)), static_cast<std::uint64_t>(sensor.rows()));
  // A fixed shuffle (Fisher-Yates with the test generator).
  Points3f shuffled = sensor;
  ds3d::test::Rng rng(41);
  for (Eigen::Index i = shuffled.rows() - 1; i > 0; --i) {
    const auto j = static_cast<Eigen::Index>(rng.next() % static_cast<std::uint64_t>(i + 1));
    shuffled.row(i).swap(shuffled.row(j));
  }
  ds3d::VoxelGridWorkspace ws;
  for (const auto& [name, cloud] :
       {std::pair<std::string, const Points3f&>{"sensor", sensor}, {"shuffled", shuffled}}) {
    const VoxelGridResult ref = brute_force_voxels(cloud, leaf);
    EXPECT_GT(ref.num_non_finite, 50U);
    expect_same(ds3d::voxel_grid(cloud, {.leaf_size = leaf}), ref, name);
    expect_same(ds3d::voxel_grid(cloud, {.leaf_size = leaf}, ws), ref, name + " workspace");
    expect_same(
        ds3d::voxel_grid(cloud, {.leaf_size = leaf, .num_threads = 3, .parallel_min_points = 0}),
        ref, name + " 3 threads");
    const VoxelGridResult three = ds3d::voxel_grid(
        cloud, {.leaf_size = leaf, .min_points = 3, .num_threads = 3, .parallel_min_points = 0});
    const VoxelGridResult one = ds3d::voxel_grid(cloud, {.leaf_size = leaf, .min_points = 3}, ws);
    expect_same(one, three, name + " min_points 3");
    EXPECT_EQ(one.num_dropped, three.num_dropped) << name;
    EXPECT_GT(one.num_dropped, 0U) << name;
  }
}

TEST(VoxelGrid, MinPointsDropsSmallVoxels) {
  ds3d::test::Rng rng(2);
  const Points3f p = ds3d::test::uniform_box(3000, {0, 0, 0}, {1, 1, 1}, rng);
  const auto all = ds3d::voxel_grid(p, {.leaf_size = 0.1});
  const auto big = ds3d::voxel_grid(p, {.leaf_size = 0.1, .min_points = 4});
  std::size_t kept = 0;
  std::size_t dropped = 0;
  for (const auto c : all.counts) (c >= 4 ? kept : dropped) += (c >= 4 ? 1 : c);
  EXPECT_EQ(static_cast<std::size_t>(big.centroids.rows()), kept);
  EXPECT_EQ(big.num_dropped, dropped);
  for (const auto c : big.counts) EXPECT_GE(c, 4U);
}

TEST(VoxelGrid, SameResultForAnyThreadCount) {
  ds3d::test::Rng rng(3);
  const Points3f p = ds3d::test::uniform_box(50'000, {-1, -1, -1}, {1, 1, 1}, rng);
  const auto r1 = ds3d::voxel_grid(p, {.leaf_size = 0.05, .num_threads = 1});
  for (const int t : {2, 4, 7, 0}) {
    const auto rt =
        ds3d::voxel_grid(p, {.leaf_size = 0.05, .num_threads = t, .parallel_min_points = 0});
    EXPECT_EQ(rt.centroids, r1.centroids);  // bit-identical
    EXPECT_EQ(rt.keys, r1.keys);
    EXPECT_EQ(rt.counts, r1.counts);
    EXPECT_EQ(rt.representative, r1.representative);
  }
}

TEST(VoxelGrid, WorkspaceReuseAndMinPointsAnyThreadCount) {
  ds3d::test::Rng rng(5);
  const Points3f big = ds3d::test::uniform_box(30'000, {-1, -2, -1}, {2, 1, 1}, rng);
  const Points3f small =
      ds3d::test::uniform_box(500, {-0.2F, -0.2F, -0.2F}, {0.2F, 0.2F, 0.2F}, rng);
  ds3d::VoxelGridWorkspace ws;
  for (const Points3f* p : {&big, &small, &big}) {  // grow, shrink, reuse
    const auto r1 = ds3d::voxel_grid(*p, {.leaf_size = 0.1, .min_points = 3});
    for (const int t : {1, 2, 3}) {
      const auto rt = ds3d::voxel_grid(
          *p, {.leaf_size = 0.1, .min_points = 3, .num_threads = t, .parallel_min_points = 0}, ws);
      EXPECT_EQ(rt.centroids, r1.centroids);
      EXPECT_EQ(rt.keys, r1.keys);
      EXPECT_EQ(rt.counts, r1.counts);
      EXPECT_EQ(rt.representative, r1.representative);
      EXPECT_EQ(rt.num_dropped, r1.num_dropped);
    }
  }
}

// The plain overload keeps its scratch in a thread-local workspace: a sequence of calls that
// grows and shrinks it, switches between the dense and sparse paths and min_points, and
// includes a call that throws, must give exactly what a fresh workspace gives, on several
// threads at once.
TEST(VoxelGrid, PlainCallsReuseThreadScratchExactly) {
  ds3d::test::Rng rng(11);
  const Points3f big = ds3d::test::uniform_box(60'000, {-1, -2, -1}, {2, 1, 1}, rng);
  const Points3f small =
      ds3d::test::uniform_box(700, {-0.3F, -0.3F, -0.3F}, {0.3F, 0.3F, 0.3F}, rng);
  Points3f bad(2, 3);
  bad << 0, 0, 0, 3.0e38F, 0, 0;  // key overflow: throws
  struct Call {
    const Points3f* p;
    double leaf;
    std::uint32_t min_points;
  };
  const std::vector<Call> calls = {{&big, 0.01, 1}, {&small, 0.05, 1}, {&big, 0.1, 3},
                                   {&bad, 1e-3, 1}, {&big, 0.01, 2},   {&small, 0.002, 1},
                                   {&big, 0.05, 1}};
  const auto run = [&](std::vector<VoxelGridResult>* out) {
    for (const Call& c : calls) {
      const ds3d::VoxelGridParams prm{.leaf_size = c.leaf, .min_points = c.min_points};
      try {
        out->push_back(ds3d::voxel_grid(*c.p, prm));
      } catch (const ds3d::InvalidArgument&) {
        out->emplace_back();
      }
    }
  };
  std::vector<VoxelGridResult> ref;
  for (const Call& c : calls) {
    ds3d::VoxelGridWorkspace fresh;
    const ds3d::VoxelGridParams prm{.leaf_size = c.leaf, .min_points = c.min_points};
    if (c.p == &bad) {
      EXPECT_THROW((void)ds3d::voxel_grid(*c.p, prm, fresh), ds3d::InvalidArgument);
      ref.emplace_back();
    } else {
      ref.push_back(ds3d::voxel_grid(*c.p, prm, fresh));
    }
  }
  std::vector<VoxelGridResult> here;
  run(&here);
  run(&here);  // second round: every buffer already grown
  std::vector<VoxelGridResult> other;
  std::thread t([&] { run(&other); });
  t.join();
  ASSERT_EQ(here.size(), 2 * calls.size());
  ASSERT_EQ(other.size(), calls.size());
  for (std::size_t i = 0; i < here.size(); ++i) {
    expect_same(here[i], ref[i % calls.size()], "call " + std::to_string(i));
  }
  for (std::size_t i = 0; i < other.size(); ++i) {
    expect_same(other[i], ref[i], "other thread, call " + std::to_string(i));
  }
  // Releasing: this thread held the scratch of the 60k-point calls (8 bytes per point in each
  // of the two sort buffers at least); a second release finds nothing; the next call still
  // gives the same result.
  EXPECT_GE(ds3d::release_voxel_grid_scratch(), 2 * 60'000 * sizeof(std::uint64_t));
  EXPECT_EQ(ds3d::release_voxel_grid_scratch(), 0U);
  expect_same(ds3d::voxel_grid(big, {.leaf_size = 0.01}), ref[0], "after release");
}

TEST(VoxelGrid, NonFiniteInput) {
  Points3f p(5, 3);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  p << 0.1F, 0.1F, 0.1F, nan, 0, 0, 0, -inf, 0, 0.12F, 0.11F, 0.13F, 0, 0, inf;
  const auto r = ds3d::voxel_grid(p, {.leaf_size = 1.0});
  EXPECT_EQ(r.num_non_finite, 3U);
  ASSERT_EQ(r.centroids.rows(), 1);
  EXPECT_EQ(r.counts[0], 2U);
  EXPECT_TRUE(r.centroids.allFinite());
  EXPECT_THROW((void)ds3d::voxel_grid(p, {.on_non_finite = ds3d::NonFinite::kThrow}),
               ds3d::InvalidArgument);
}

// float64 coordinates beyond the float32 range read as inf: named, not counted as non-finite.
TEST(VoxelGrid, Float64BeyondFloat32RangeIsNamed) {
  ds3d::Points3d p(4, 3);
  p << 0.1, 0.2, 0.3, 1.0, 2.0, 3.0, 0.5, 1.25e39, 0.5, 0.0, 0.0, 0.0;
  for (const auto policy : {ds3d::NonFinite::kSkip, ds3d::NonFinite::kThrow}) {
    try {
      (void)ds3d::voxel_grid(p, {.leaf_size = 0.1, .on_non_finite = policy});
      FAIL() << "expected InvalidArgument";
    } catch (const ds3d::InvalidArgument& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("ds3d::voxel_grid: points: row 2 y = 1.25e+39"), std::string::npos) << msg;
      EXPECT_NE(msg.find("float32 range"), std::string::npos) << msg;
    }
  }
  // Through the Eigen::Ref overload, and with real non-finite points next to normal ones.
  p(2, 1) = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Ref<const ds3d::Points3d> ref(p);
  EXPECT_EQ(ds3d::voxel_grid(ref, {.leaf_size = 0.1}).num_non_finite, 1U);
  p(3, 0) = -1e300;
  EXPECT_THROW((void)ds3d::voxel_grid(ref, {.leaf_size = 0.1}), ds3d::InvalidArgument);
}

TEST(VoxelGrid, RejectsBadParams) {
  const Points3f p = Points3f::Zero(3, 3);
  EXPECT_THROW((void)ds3d::voxel_grid(p, {.leaf_size = -0.1}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::voxel_grid(p, {.leaf_size = 0.0}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::voxel_grid(p, {.leaf_size = {0.1, std::nan(""), 0.1}}),
               ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::voxel_grid(p, {.leaf_size = {0.1, 0.1, HUGE_VAL}}),
               ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::voxel_grid(p, {.min_points = 0}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::voxel_grid(p, {.num_threads = -1}), ds3d::InvalidArgument);
  try {
    (void)ds3d::voxel_grid(p, {.leaf_size = -0.1});
    FAIL();
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("ds3d::voxel_grid: leaf_size.dx"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("-0.1"), std::string::npos);
  }
}

TEST(VoxelGrid, KeyOverflowThrowsNamingTheValue) {
  Points3f p(2, 3);
  p << 0, 0, 0, 3.0e38F, 0, 0;
  try {
    (void)ds3d::voxel_grid(p, {.leaf_size = 1e-3});
    FAIL() << "expected InvalidArgument";
  } catch (const ds3d::InvalidArgument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("ds3d::voxel_grid"), std::string::npos) << msg;
    EXPECT_NE(msg.find("x = 3"), std::string::npos) << msg;
    EXPECT_NE(msg.find("overflow"), std::string::npos) << msg;
  }
  // Large but representable keys use the comparison-sort path and stay exact.
  Points3f q(3, 3);
  q << -1e6F, 5e5F, -2e6F, 1e6F, -5e5F, 2e6F, 1e6F, -5e5F, 2e6F;
  const auto r = ds3d::voxel_grid(q, {.leaf_size = 1e-9});
  ASSERT_EQ(r.centroids.rows(), 2);
  EXPECT_EQ(r.keys(0, 0), static_cast<std::int64_t>(std::floor(-1e6 / 1e-9)));
  EXPECT_EQ(r.counts[1], 2U);
}

// Typed test over the shipped adaptors and a user point type.
struct UserPoint {
  double x, y, z;
  int label;
};
using UserCloud = std::vector<UserPoint>;

}  // namespace

template <>
struct ds3d::PointCloudTraits<UserCloud> {
  static std::size_t size(const UserCloud& c) { return c.size(); }
  static Eigen::Vector3f point(const UserCloud& c, std::size_t i) {
    return Eigen::Vector3d(c[i].x, c[i].y, c[i].z).cast<float>();
  }
};

namespace {

template <class C>
C convert(const Points3f& p);
template <>
Points3f convert(const Points3f& p) {
  return p;
}
template <>
std::vector<Eigen::Vector3f> convert(const Points3f& p) {
  std::vector<Eigen::Vector3f> v;
  for (Eigen::Index i = 0; i < p.rows(); ++i) v.emplace_back(p.row(i).transpose());
  return v;
}
template <>
UserCloud convert(const Points3f& p) {
  UserCloud v;
  for (Eigen::Index i = 0; i < p.rows(); ++i) v.push_back({p(i, 0), p(i, 1), p(i, 2), 0});
  return v;
}

template <class C>
class VoxelGridTyped : public ::testing::Test {};
using CloudTypes = ::testing::Types<Points3f, std::vector<Eigen::Vector3f>, UserCloud>;
TYPED_TEST_SUITE(VoxelGridTyped, CloudTypes);

TYPED_TEST(VoxelGridTyped, SameAsPoints3f) {
  ds3d::test::Rng rng(4);
  const Points3f p = ds3d::test::plane_points(5000, 2.0, 0.01, rng);
  const TypeParam c = convert<TypeParam>(p);
  const auto ref = ds3d::voxel_grid(p, {.leaf_size = 0.1});
  const auto r = ds3d::voxel_grid(c, {.leaf_size = 0.1});
  EXPECT_EQ(r.centroids, ref.centroids);
  EXPECT_EQ(r.keys, ref.keys);
  EXPECT_EQ(r.representative, ref.representative);
}

}  // namespace
