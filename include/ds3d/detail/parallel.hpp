// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Minimal fork-join helpers over std::thread. No global state, no OpenMP: each call resolves its
// own `num_threads` (STYLE.md §6). Not API.

#include <algorithm>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "ds3d/errors.hpp"

namespace ds3d::detail {

/// Maps the user's `num_threads` (0 = hardware concurrency, > 0 as given) to a thread count;
/// throws InvalidArgument naming `function` for negative values.
[[nodiscard]] inline int resolve_num_threads(int num_threads, const char* function) {
  DS3D_CHECK(num_threads >= 0, function, ": num_threads must be >= 0 (got ", num_threads, ")");
  if (num_threads == 0) {
    const unsigned hw = std::thread::hardware_concurrency();
    return hw == 0 ? 1 : static_cast<int>(hw);
  }
  return num_threads;
}

/// Splits [0, n) into `num_chunks` contiguous chunks of near-equal size; returns chunk c's range.
[[nodiscard]] inline std::pair<std::size_t, std::size_t> chunk_range(std::size_t n,
                                                                     std::size_t num_chunks,
                                                                     std::size_t c) {
  const std::size_t base = n / num_chunks;
  const std::size_t rem = n % num_chunks;
  const std::size_t begin = c * base + std::min(c, rem);
  return {begin, begin + base + (c < rem ? 1 : 0)};
}

/// Runs body(begin, end, chunk) over `num_chunks` contiguous chunks of [0, n) on up to
/// `num_threads` threads (the calling thread takes chunk 0). Chunk boundaries depend only on n
/// and num_chunks, so callers get deterministic results by combining per-chunk outputs in chunk
/// order. The first exception thrown by any chunk is rethrown after all threads have joined.
template <class Body>
void parallel_chunks(std::size_t n, std::size_t num_chunks, int num_threads, Body&& body) {
  num_chunks = std::max<std::size_t>(1, std::min(num_chunks, std::max<std::size_t>(n, 1)));
  const auto threads = static_cast<std::size_t>(std::max(1, num_threads));
  if (threads == 1 || num_chunks == 1) {
    for (std::size_t c = 0; c < num_chunks; ++c) {
      const auto [b, e] = chunk_range(n, num_chunks, c);
      body(b, e, c);
    }
    return;
  }
  std::exception_ptr error;
  std::mutex error_mutex;
  const std::size_t workers = std::min(threads, num_chunks);
  auto run_worker = [&](std::size_t w) {
    // Static round-robin assignment of chunks to workers: deterministic and cheap.
    for (std::size_t c = w; c < num_chunks; c += workers) {
      try {
        const auto [b, e] = chunk_range(n, num_chunks, c);
        body(b, e, c);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(workers - 1);
  for (std::size_t w = 1; w < workers; ++w) pool.emplace_back(run_worker, w);
  run_worker(0);
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

/// parallel_chunks with one chunk per thread.
template <class Body>
void parallel_for(std::size_t n, int num_threads, Body&& body) {
  parallel_chunks(n, static_cast<std::size_t>(std::max(1, num_threads)), num_threads,
                  std::forward<Body>(body));
}

}  // namespace ds3d::detail
