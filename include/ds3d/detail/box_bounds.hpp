// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file box_bounds.hpp
/// @brief Axis-aligned bounds of 3-D points listed by index (the KD-tree builds of
/// kdtree_nd.hpp and mst.hpp share it).

#include <algorithm>
#include <cstddef>
#include <cstdint>

namespace ds3d::detail {

/// Extends lo[0..2] / hi[0..2] by the points data[3 * order[i] ...], i in [b, e), with the
/// box held in registers; the min/max sequence is that of the plain per-coordinate loop, so the
/// result is bitwise the same.
inline void extend_box3(const double* data, const std::uint32_t* order, std::uint32_t b,
                        std::uint32_t e, double* lo, double* hi) {
  double l0 = lo[0], l1 = lo[1], l2 = lo[2], h0 = hi[0], h1 = hi[1], h2 = hi[2];
  for (auto i = b; i < e; ++i) {
    const double* p = data + static_cast<std::size_t>(order[i]) * 3;
    l0 = std::min(l0, p[0]);
    h0 = std::max(h0, p[0]);
    l1 = std::min(l1, p[1]);
    h1 = std::max(h1, p[1]);
    l2 = std::min(l2, p[2]);
    h2 = std::max(h2, p[2]);
  }
  lo[0] = l0;
  lo[1] = l1;
  lo[2] = l2;
  hi[0] = h0;
  hi[1] = h1;
  hi[2] = h2;
}

}  // namespace ds3d::detail
