// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/detail/parallel.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <stdexcept>
#include <vector>

namespace {

TEST(Parallel, ResolveNumThreads) {
  EXPECT_EQ(ds3d::detail::resolve_num_threads(3, "f"), 3);
  EXPECT_GE(ds3d::detail::resolve_num_threads(0, "f"), 1);
  try {
    (void)ds3d::detail::resolve_num_threads(-2, "ds3d::f");
    FAIL();
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_STREQ(e.what(), "ds3d::f: num_threads must be >= 0 (got -2)");
  }
}

TEST(Parallel, ChunksCoverRangeExactlyOnce) {
  for (std::size_t n : {0U, 1U, 7U, 100U, 1001U}) {
    for (std::size_t chunks : {1U, 2U, 3U, 16U}) {
      for (int threads : {1, 2, 4}) {
        std::vector<std::atomic<int>> hits(n);
        std::vector<std::size_t> chunk_of(n, 999);
        ds3d::detail::parallel_chunks(n, chunks, threads,
                                      [&](std::size_t b, std::size_t e, std::size_t c) {
                                        for (std::size_t i = b; i < e; ++i) {
                                          hits[i]++;
                                          chunk_of[i] = c;
                                        }
                                      });
        for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i].load(), 1) << n << " " << chunks;
        EXPECT_TRUE(std::is_sorted(chunk_of.begin(), chunk_of.end()));
      }
    }
  }
}

TEST(Parallel, RethrowsAfterJoining) {
  std::atomic<int> done{0};
  EXPECT_THROW(ds3d::detail::parallel_chunks(100, 4, 2,
                                             [&](std::size_t b, std::size_t, std::size_t) {
                                               done++;
                                               if (b == 0) throw std::runtime_error("chunk 0");
                                             }),
               std::runtime_error);
  EXPECT_EQ(done.load(), 4);
}

}  // namespace
