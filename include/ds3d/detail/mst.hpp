// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Exact minimum spanning trees of the mutual-reachability graph
// d_mr(i,j) = max{core(i), core(j), d(i,j)}: what Prim (mst_prim.hpp) and KD-tree Borůvka
// (mst_boruvka.hpp) share, the run-time choice of their SIMD steps, and the entry points.
// Not API: see ds3d/cluster/hdbscan.hpp.

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/detail/box_bounds.hpp"
#include "ds3d/detail/kdtree_nd.hpp"
#include "ds3d/detail/parallel.hpp"

namespace ds3d::detail {

// Which Prim step prim_dense runs. kAuto picks the widest one the CPU runs (AVX-512F, AVX2,
// SSE2 for D = 3; generic otherwise); the others exist so tests can check that every step gives
// bitwise the same tree. A forced step that the build or the CPU cannot run (see
// prim_step_available) falls back to kAuto's choice.
enum class PrimStep : std::uint8_t { kAuto, kGeneric, kSse2, kAvx2, kAvx512 };

// How BoruvkaKdTree finds the core distances (D = 3, k + 1 <= 16): several queries per tree
// walk, one per SIMD lane (kAvx2: 4, kAvx512: 8), or one walk per query (kPerQuery, also used for
// other D and k). kAuto picks the widest the build and the CPU run; a forced mode that cannot run
// falls back to kAuto's choice. All give bitwise the same results (tests run each).
enum class KnnLanes : std::uint8_t { kAuto, kPerQuery, kAvx2, kAvx512 };

#if defined(__x86_64__) && defined(__GNUC__)
#define DS3D_HDBSCAN_AVX2 1
// no_contract() for functions with a target attribute: target("avx512f") enables FMA inside the
// function although the translation unit's __FMA__ is off, so the barrier must be unconditional.
inline double no_contract_x86(double p) {
  asm("" : "+v"(p));
  return p;
}

#define DS3D_HDBSCAN_AVX512 1
// GCC 12's _mm512_max_pd uses _mm512_undefined_pd, which trips a false
// -Wmaybe-uninitialized under -Werror.
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
inline __attribute__((target("avx512f"))) __m512d no_contract_v512(__m512d v) {
  asm("" : "+v"(v));  // no FMA contraction across this product, whatever -ffp-contract says
  return v;
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif

inline bool cpu_has_avx512() {
  static const bool has = __builtin_cpu_supports("avx512f") != 0;
  return has;
}

inline bool cpu_has_avx2() {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}
#endif

// Queries per BoruvkaKdTree core-distance walk (SIMD lanes) for dimension dim, list length kk =
// k + 1 and mode `lanes`: 8 (AVX-512F), 4 (AVX2) or 0 (one walk per query).
inline std::size_t knn_lane_width(std::size_t dim, std::size_t kk, KnnLanes lanes) {
  if (dim != 3 || kk > 16 || lanes == KnnLanes::kPerQuery) return 0;
  bool avx2 = false;
  bool avx512 = false;
#if defined(__AVX2__)
  avx2 = true;
#endif
#if defined(DS3D_HDBSCAN_AVX512)
  avx512 = cpu_has_avx512();
#endif
  if (lanes == KnnLanes::kAvx2 && avx2) return 4;
  if (avx512) return 8;
  return avx2 ? 4 : 0;
}

inline bool prim_step_available(PrimStep step, std::size_t dim) {
  switch (step) {
    case PrimStep::kGeneric:
      return true;
    case PrimStep::kSse2:
#if defined(__SSE2__)
      return dim == 3;
#else
      return false;
#endif
    case PrimStep::kAvx2:
#if defined(DS3D_HDBSCAN_AVX2)
      return dim == 3 && cpu_has_avx2();
#else
      return false;
#endif
    case PrimStep::kAvx512:
#if defined(DS3D_HDBSCAN_AVX512)
      return dim == 3 && cpu_has_avx512();
#else
      return false;
#endif
    default:
      return false;
  }
}

// Prim on the implicit dense graph (n × dim row-major points, core distances `core`), with the
// given step (see PrimStep). Defined in mst_prim.hpp.
inline std::vector<MstEdge> prim_dense(const double* data, std::size_t n, std::size_t dim,
                                       const std::vector<double>& core,
                                       PrimStep step = PrimStep::kAuto);

// Prim on a precomputed dense distance matrix (row-major n × n). O(n²) time, O(n) memory.
inline std::vector<MstEdge> prim_precomputed(const double* dist, std::size_t n,
                                             const std::vector<double>& core);

// Core distances (k-th nearest other point, 1 <= k < n) into `core` and the MST by KD-tree
// Borůvka, sharing one tree. Defined in mst_boruvka.hpp.
inline std::vector<MstEdge> boruvka_kdtree(const double* data, std::size_t n, std::size_t dim,
                                           std::size_t k, int num_threads,
                                           std::vector<double>& core,
                                           KnnLanes lanes = KnnLanes::kAuto);

// Core distances (k-th nearest other point, 1 <= k < n) only, by BoruvkaKdTree's search.
inline std::vector<double> boruvka_core_distances(const double* data, std::size_t n,
                                                  std::size_t dim, std::size_t k, int num_threads,
                                                  KnnLanes lanes = KnnLanes::kAuto);

}  // namespace ds3d::detail

// Last, after every shared declaration: each part includes this header first, so that any of
// them may be included on its own.
#include "ds3d/detail/mst_boruvka.hpp"
#include "ds3d/detail/mst_prim.hpp"
