// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// numpy's default argsort (kind='quicksort': introsort with median-of-3 pivots, insertion sort
// for partitions of up to 16 elements, heapsort past 2·log2(n) levels) for finite doubles,
// reproduced so that the order of equal values is numpy's. Used to order equal-weight MST edges
// like the reference hdbscan. Not API.

#include <cstddef>
#include <numeric>
#include <utility>
#include <vector>

namespace ds3d::detail {

/// numpy's aheapsort on idx[0..n-1] (1-based heap indexing as in numpy).
inline void numpy_aheapsort(const double* v, std::size_t* idx, std::size_t n) {
  std::size_t* a = idx - 1;
  const auto sift = [&](std::size_t i, std::size_t len, std::size_t tmp) {
    for (std::size_t j = i << 1; j <= len;) {
      if (j < len && v[a[j]] < v[a[j + 1]]) ++j;
      if (!(v[tmp] < v[a[j]])) break;
      a[i] = a[j];
      i = j;
      j += j;
    }
    a[i] = tmp;
  };
  for (std::size_t l = n >> 1; l > 0; --l) sift(l, n, a[l]);
  for (; n > 1;) {
    const std::size_t tmp = a[n];
    a[n] = a[1];
    n -= 1;
    sift(1, n, tmp);
  }
}

/// Indices that sort v like numpy.argsort(v) (default kind) does, ties included.
inline std::vector<std::size_t> numpy_argsort(const std::vector<double>& v) {
  constexpr std::ptrdiff_t kSmall = 15;
  std::vector<std::size_t> idx(v.size());
  std::iota(idx.begin(), idx.end(), std::size_t{0});
  if (v.size() < 2) return idx;
  const double* x = v.data();
  int cdepth = 0;
  for (std::size_t m = v.size(); m >>= 1;) ++cdepth;
  cdepth *= 2;
  std::vector<std::pair<std::size_t*, std::size_t*>> stack;
  std::vector<int> depth;
  std::size_t* pl = idx.data();
  std::size_t* pr = idx.data() + v.size() - 1;
  for (;;) {
    if (cdepth < 0) {
      numpy_aheapsort(x, pl, static_cast<std::size_t>(pr - pl + 1));
    } else {
      while (pr - pl > kSmall) {
        std::size_t* pm = pl + ((pr - pl) >> 1);
        if (x[*pm] < x[*pl]) std::swap(*pm, *pl);
        if (x[*pr] < x[*pm]) std::swap(*pr, *pm);
        if (x[*pm] < x[*pl]) std::swap(*pm, *pl);
        const double vp = x[*pm];
        std::size_t* pi = pl;
        std::size_t* pj = pr - 1;
        std::swap(*pm, *pj);
        for (;;) {
          do ++pi;
          while (x[*pi] < vp);
          do --pj;
          while (vp < x[*pj]);
          if (pi >= pj) break;
          std::swap(*pi, *pj);
        }
        std::swap(*pi, *(pr - 1));
        // Push the larger partition, continue with the smaller one.
        if (pi - pl < pr - pi) {
          stack.emplace_back(pi + 1, pr);
          pr = pi - 1;
        } else {
          stack.emplace_back(pl, pi - 1);
          pl = pi + 1;
        }
        depth.push_back(--cdepth);
      }
      for (std::size_t* pi = pl + 1; pi <= pr; ++pi) {  // insertion sort
        const std::size_t vi = *pi;
        const double vpi = x[vi];
        std::size_t* pj = pi;
        for (std::size_t* pk = pi - 1; pj > pl && vpi < x[*pk]; --pk) *pj-- = *pk;
        *pj = vi;
      }
    }
    if (stack.empty()) break;
    pl = stack.back().first;
    pr = stack.back().second;
    stack.pop_back();
    cdepth = depth.back();
    depth.pop_back();
  }
  return idx;
}

}  // namespace ds3d::detail
