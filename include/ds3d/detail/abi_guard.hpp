// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Link-time check that a translation unit using the compiled libraries shares their Eigen ABI.
#pragma once

#include <Eigen/Core>

// The compiled libraries (ds3d::htx, ds3d::slam) exchange Eigen objects with the code that calls
// them: dynamic matrices allocated on one side are freed on the other, and structs hold
// fixed-size vectorisable members. Eigen 3.4 allocates heap blocks with plain malloc when its
// default alignment is 16 bytes and with a hand-made 32-byte aligned allocator under AVX (even
// with EIGEN_MAX_ALIGN_BYTES=16), and aligns fixed-size members to EIGEN_MAX_STATIC_ALIGN_BYTES;
// code with another setting crashes or reads shifted members. Every translation unit including a
// header of a compiled library refers to a symbol named after its own two alignments, and only
// the library's own pair is defined (src/htx/abi_guard.cpp), so a mismatch fails to link with
// "undefined reference to ds3d_eigen_abi_heap<H>_fixed<F>" instead of crashing at run time.
// The header-only core (ds3d::core) does not use this: it is compiled with the consumer's flags.
#define DS3D_ABI_CAT_IMPL(a, b, c, d) a##b##c##d
#define DS3D_ABI_CAT(a, b, c, d) DS3D_ABI_CAT_IMPL(a, b, c, d)
#define DS3D_EIGEN_ABI_SYMBOL \
  DS3D_ABI_CAT(ds3d_eigen_abi_heap, EIGEN_DEFAULT_ALIGN_BYTES, _fixed, EIGEN_MAX_STATIC_ALIGN_BYTES)

extern "C" const int DS3D_EIGEN_ABI_SYMBOL;

namespace ds3d::detail {
namespace {
// Internal linkage and `used`: emitted in every translation unit, so the reference is kept.
[[gnu::used]] const int* const eigen_abi_guard = &DS3D_EIGEN_ABI_SYMBOL;
}  // namespace
}  // namespace ds3d::detail
