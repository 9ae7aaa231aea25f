// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// %s Part of ds3d::voxel_grid (see voxel_grid_impl.hpp). Not API.

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

#include "ds3d/detail/parallel.hpp"
#include "ds3d/detail/voxel_grid_rows.hpp"
#include "ds3d/detail/voxel_key.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"

namespace ds3d::detail {

/// Stable LSD radix sort of a[0, m) by `passes` digits of `digit` bits from bit `base` up, using
/// `tmp` (m words) and the histograms already counted in `hist` (passes × 2^digit); returns the
/// buffer holding the result.
inline std::uint64_t* radix_sort_pairs(std::uint64_t* a, std::uint64_t* tmp, std::size_t m,
                                       std::uint32_t* hist, int passes, int digit, int base) {
  const std::size_t buckets = std::size_t{1} << digit;
  const std::uint64_t mask = buckets - 1;
  for (int p = 0; p < passes; ++p) {
    std::uint32_t* c = hist + static_cast<std::size_t>(p) * buckets;
    std::uint32_t sum = 0;
    for (std::size_t b = 0; b < buckets; ++b) {
      const std::uint32_t t = c[b];
      c[b] = sum;
      sum += t;
    }
    const int shift = base + p * digit;
    for (std::size_t k = 0; k < m; ++k) {
      const std::uint64_t w = a[k];
      tmp[c[(w >> shift) & mask]++] = w;
    }
    std::swap(a, tmp);
  }
  return a;
}

/// Exclusive prefix sums of c[0, len) in place.
inline void exclusive_prefix(std::uint32_t* c, std::size_t len) {
  std::uint32_t sum = 0;
  for (std::size_t k = 0; k < len; ++k) {
    const std::uint32_t cnt = c[k];
    c[k] = sum;
    sum += cnt;
  }
}

/// Sparse path, keys of 23 to 32 bits: the keys (parallel, into the first half of ws.words)
/// and their stable sort as (key << 32 | index) pairs with the (y, z) fields (`low` bits, at most
/// log2(n) and 22) as one digit and the x field (`bits - low` <= 11 bits) as the other. Returns the
/// buffer holding the sorted pairs.
///
/// A depth frame arrives in sensor order: along an image row the (y, z) voxel moves by one
/// z step at a time (y is proportional to z for a fixed row), so the 2^low-bucket scatter of the
/// first pass writes to a few hundred places that it revisits (good locality) and the sort needs
/// two passes instead of three. In an arbitrary order (a shuffled cloud) that scatter misses the
/// cache at every point; hence the key pass counts the points whose (y, z) digit lies less than
/// one y step from the previous point's, and when fewer than half do, the (y, z) digit is split
/// into two (histograms derived from the joint one) and the sort makes the usual three passes.
/// Same output either way (a stable LSD sort over the same bits).
template <PointCloud C>
[[nodiscard]] const std::uint64_t* sort_pairs_yz_x(const C& cloud, int threads, const KeyGrid& g,
                                                   int bits, unsigned low, unsigned bz,
                                                   VoxelGridWorkspace& ws) {
  constexpr const char* kFn = "ds3d::voxel_grid";
  const std::size_t n = cloud::size(cloud);
  const unsigned high = static_cast<unsigned>(bits) - low;
  const std::size_t n_low = std::size_t{1} << low;
  const std::size_t n_high = std::size_t{1} << high;
  const auto low_mask = static_cast<std::uint32_t>(n_low - 1);
  const auto high_mask = static_cast<std::uint32_t>(n_high - 1);
  const unsigned wa = low / 2;  // fallback digits: [0, wa) and [wa, low), each <= 11 bits
  const std::size_t n_a = std::size_t{1} << wa;
  const std::size_t n_b = std::size_t{1} << (low - wa);
  // One joint and one x histogram per chunk of the (parallel) key pass, summed into chunk 0's.
  const auto chunks = static_cast<std::size_t>(std::max(1, threads));
  const std::size_t per_chunk = n_low + n_high;
  ws.hist.assign(chunks * per_chunk + n_a + n_b, 0U);
  std::uint32_t* const h_low = ws.hist.data();
  std::uint32_t* const h_high = h_low + n_low;
  std::uint32_t* const h_a = ws.hist.data() + chunks * per_chunk;
  std::uint32_t* const h_b = h_a + n_a;
  std::uint64_t* const a = ws.words.get();
  std::uint64_t* const t = ws.tmp.get();
  auto* const key_bytes = reinterpret_cast<unsigned char*>(a);
  // |d| < 2^bz for the (y, z) digit difference d, as one unsigned compare.
  const std::uint32_t step = std::uint32_t{1} << bz;
  ws.runs.assign(chunks, 0);  // points near their predecessor, per chunk
  auto pass_keys = [&](std::size_t b0, std::size_t e0, std::size_t ch) {
    std::uint32_t* const hl = h_low + ch * per_chunk;
    std::uint32_t* const hh = hl + n_low;
    std::size_t near = 0;
    std::uint32_t prev = 0;  // (y, z) digit of the previous block's last point
    for_each_key_block(
        cloud, b0, e0, g, kFn, [&](std::size_t s, std::size_t len, const std::uint32_t* keys) {
          std::memcpy(key_bytes + 4 * s, keys, 4 * len);
          for (std::size_t j = 0; j < len; ++j) {
            const std::uint32_t key = keys[j];
            ++hl[key & low_mask];
            ++hh[(key >> low) & high_mask];
          }
          std::size_t blk_near = ((keys[0] & low_mask) - prev + (step - 1)) < 2 * step - 1 ? 1 : 0;
          for (std::size_t j = 1; j < len; ++j) {  // vectorises
            const std::uint32_t d = (keys[j] & low_mask) - (keys[j - 1] & low_mask);
            blk_near += d + (step - 1) < 2 * step - 1 ? 1 : 0;
          }
          near += blk_near;
          prev = keys[len - 1] & low_mask;
        });
    ws.runs[ch] = near;
  };
  if (chunks == 1) {
    pass_keys(0, n, 0);
  } else {
    parallel_chunks(n, chunks, threads, pass_keys);
    for (std::size_t ch = 1; ch < chunks; ++ch) {
      const std::uint32_t* src = h_low + ch * per_chunk;
      for (std::size_t k = 0; k < per_chunk; ++k) h_low[k] += src[k];  // vectorises
    }
  }
  std::size_t near = 0;
  for (std::size_t ch = 0; ch < chunks; ++ch) near += ws.runs[ch];
  auto key_at = [key_bytes](std::size_t k) {
    std::uint32_t key;
    std::memcpy(&key, key_bytes + 4 * k, 4);
    return key;
  };
  // First pass: pairs (key << 32 | index) placed by the key digit under `mask`; later passes:
  // pairs moved by the digit `shift` bits above the key's lowest bit.
  auto scatter_keys = [&](std::uint64_t* dst, std::uint32_t* h, std::uint32_t mask) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint32_t key = key_at(k);
      dst[h[key & mask]++] = (std::uint64_t{key} << 32U) | k;
    }
  };
  auto scatter_pairs = [n](const std::uint64_t* src, std::uint64_t* dst, std::uint32_t* h,
                           unsigned shift, std::uint32_t mask) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint64_t w = src[k];
      dst[h[(w >> (32U + shift)) & mask]++] = w;
    }
  };
  exclusive_prefix(h_high, n_high);
  if (2 * near >= n) {  // sensor order: two passes, (y, z) then x
    exclusive_prefix(h_low, n_low);
    scatter_keys(t, h_low, low_mask);
    scatter_pairs(t, a, h_high, low, high_mask);
    return a;
  }
  // Arbitrary order: three passes; the histograms of the two (y, z) digits are the row and column
  // sums of the joint one (contiguous rows of 2^wa counters: vectorised adds).
  for (std::size_t row = 0; row < n_b; ++row) {
    const std::uint32_t* src = h_low + (row << wa);
    std::uint32_t sum = 0;
    for (std::size_t i = 0; i < n_a; ++i) {
      h_a[i] += src[i];
      sum += src[i];
    }
    h_b[row] = sum;
  }
  exclusive_prefix(h_a, n_a);
  exclusive_prefix(h_b, n_b);
  const auto mask_a = static_cast<std::uint32_t>(n_a - 1);
  const auto mask_b = static_cast<std::uint32_t>(n_b - 1);
  scatter_keys(t, h_a, mask_a);
  scatter_pairs(t, a, h_b, wa, mask_b);
  scatter_pairs(a, t, h_high, low, high_mask);
  return t;
}

/// Sparse path, general digits: keys (parallel) with all radix histograms, then a stable LSD
/// radix sort over the used bits in 0 to 3 passes of equal digits (<= 11 bits). Returns the
/// buffer holding the sorted pairs.
template <PointCloud C>
[[nodiscard]] const std::uint64_t* sort_pairs_digits(const C& cloud, int threads, const KeyGrid& g,
                                                     int bits, VoxelGridWorkspace& ws) {
  constexpr const char* kFn = "ds3d::voxel_grid";
  const std::size_t n = cloud::size(cloud);
  const int passes = (bits + 10) / 11;
  const int digit = passes == 0 ? 0 : (bits + passes - 1) / passes;
  const std::size_t buckets = std::size_t{1} << digit;
  const std::uint64_t dmask = buckets - 1;
  // Pass 2: 32-bit keys (stored in the first half of `a`, read back as bytes: the buffer is
  // typed uint64) and all radix histograms (always three: a pass beyond `passes` sees only zero
  // bits, so the counting loop has no inner loop), one set per chunk.
  const auto chunks = static_cast<std::size_t>(std::max(1, threads));
  ws.hist.assign(buckets * 3 * chunks, 0U);
  std::uint64_t* a = ws.words.get();
  std::uint64_t* const t = ws.tmp.get();
  auto* const key_bytes = reinterpret_cast<unsigned char*>(a);
  auto pass_keys = [&](std::size_t b0, std::size_t e0, std::size_t ch) {
    std::uint32_t* h = ws.hist.data() + 3 * buckets * ch;
    for_each_key_block(cloud, b0, e0, g, kFn,
                       [&](std::size_t s, std::size_t len, const std::uint32_t* keys) {
                         std::memcpy(key_bytes + 4 * s, keys, 4 * len);
                         for (std::size_t j = 0; j < len; ++j) {
                           const std::uint32_t key = keys[j];
                           ++h[key & dmask];
                           ++h[buckets + ((key >> digit) & dmask)];
                           ++h[2 * buckets + ((key >> (2 * digit)) & dmask)];
                         }
                       });
  };
  if (chunks == 1) {
    pass_keys(0, n, 0);
  } else {
    parallel_chunks(n, chunks, threads, pass_keys);
    for (std::size_t ch = 1; ch < chunks; ++ch) {
      for (std::size_t k = 0; k < 3 * buckets; ++k) {
        ws.hist[k] += ws.hist[3 * buckets * ch + k];
      }
    }
  }
  // Pass 3: stable radix sort over the used bits only (0 to 3 passes); kNoKey pairs end last.
  // Its first pass reads the keys and writes (key << 32 | index) pairs into t.
  const std::uint64_t* sorted = t;
  {
    std::uint32_t* c = ws.hist.data();
    std::uint32_t sum = 0;
    for (std::size_t k = 0; k < buckets; ++k) {
      const std::uint32_t cnt = c[k];
      c[k] = sum;
      sum += cnt;
    }
    const std::uint64_t mask = passes == 0 ? 0 : dmask;  // no pass: one bucket, input order
    for (std::size_t k = 0; k < n; ++k) {
      std::uint32_t key;
      std::memcpy(&key, key_bytes + 4 * k, 4);
      t[c[key & mask]++] = (std::uint64_t{key} << 32U) | k;
    }
    if (passes > 1) {
      sorted = radix_sort_pairs(t, a, n, ws.hist.data() + buckets, passes - 1, digit, 32 + digit);
    }
  }
  return sorted;
}

/// Sparse-box path of voxel_grid: (key << 32 | index) pairs, bit-packed keys of `bits` <= 32
/// bits (kNoKey, all ones, sorts last), stable LSD radix sort, then one row per run of equal keys.
template <PointCloud C>
void voxel_grid_sorted(const C& cloud, const VoxelGridParams& params, int threads, const KeyGrid& g,
                       const std::array<int, 3>& b, int bits, VoxelGridWorkspace& ws,
                       VoxelGridResult& r) {
  const std::size_t n = cloud::size(cloud);
  if (ws.capacity < n) {  // default-initialised: no zero-fill of buffers written before read
    ws.words = make_scratch<std::uint64_t>(n);
    ws.tmp = make_scratch<std::uint64_t>(n);
    ws.capacity = n;
  }
  // Passes 2 and 3: keys, then their stable radix sort as pairs (kNoKey pairs end last). Where
  // three equal digits would be needed (23 to 32 bits): when the (y, z) fields fit in a digit of
  // at most 22 bits (its fallback halves are <= 11 bits, like every other digit) whose counters,
  // one set per thread, take no more memory than the keys (chunks * 2^low <= n), and the x field
  // in one of at most 11, the two-digit split of sort_pairs_yz_x.
  const int passes = (bits + 10) / 11;
  const auto low = static_cast<unsigned>(b[1] + b[2]);  // bits of the (y, z) fields
  const auto chunks = static_cast<std::size_t>(std::max(1, threads));
  const bool yz_x = passes == 3 && bits - static_cast<int>(low) <= 11 && low <= 22 &&
                    chunks * (std::size_t{1} << low) <= n;
  const std::uint64_t* const sorted =
      yz_x ? sort_pairs_yz_x(cloud, threads, g, bits, low, static_cast<unsigned>(b[2]), ws)
           : sort_pairs_digits(cloud, threads, g, bits, ws);
  voxel_rows_sorted(cloud, params, threads, g, b, sorted, ws, r);
}

}  // namespace ds3d::detail
