# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# DS3D_SIMD: SIMD level of our own compiled targets (library, tests, benches, tools, Python module).
#   auto (default) - avx2 when the compiler accepts -mavx2 -mfma AND the build host runs AVX2+FMA
#                    code (never when cross-compiling); else none
#   avx2           - -mavx2 -mfma (error if the compiler rejects them; the host is not checked, so
#                    binaries built this way need an AVX2+FMA CPU: Haswell / Zen or newer)
#   none           - the compiler's baseline (SSE2 on x86-64)
# These flags are PRIVATE to our compiled targets; nothing puts them on ds3d::core, ds3d::htx or
# ds3d::slam users. EIGEN_MAX_ALIGN_BYTES=16 (every configuration) gives fixed-size Eigen members
# the layout of a default SSE build. It does NOT unify the heap allocator (Eigen 3.4 uses its
# 32-byte hand-made aligned malloc under AVX, plain malloc under SSE), so code that exchanges
# Eigen heap objects with the compiled libraries needs the same flags: the opt-in target
# ds3d::abi carries them (CMakeLists.txt), include/ds3d/detail/abi_guard.hpp checks them at link
# time; see docs/install.md.
include(CheckCXXCompilerFlag)
include(CheckCXXSourceRuns)

set(DS3D_SIMD "auto" CACHE STRING "SIMD level of ds3d's compiled targets: auto, avx2 or none")
set_property(CACHE DS3D_SIMD PROPERTY STRINGS auto avx2 none)
if(NOT DS3D_SIMD MATCHES "^(auto|avx2|none)$")
  message(FATAL_ERROR "DS3D_SIMD must be auto, avx2 or none (got '${DS3D_SIMD}')")
endif()

set(DS3D_SIMD_FLAGS_AVX2 -mavx2 -mfma)
set(DS3D_SIMD_LEVEL none)
set(_ds3d_simd_why "DS3D_SIMD=none")
if(NOT DS3D_SIMD STREQUAL "none")
  check_cxx_compiler_flag("-mavx2 -mfma" DS3D_COMPILER_HAS_AVX2_FMA)
  if(DS3D_SIMD STREQUAL "avx2")
    if(NOT DS3D_COMPILER_HAS_AVX2_FMA)
      message(FATAL_ERROR "DS3D_SIMD=avx2 but ${CMAKE_CXX_COMPILER} rejects -mavx2 -mfma")
    endif()
    set(DS3D_SIMD_LEVEL avx2)
    set(_ds3d_simd_why "DS3D_SIMD=avx2 (host not checked)")
  elseif(NOT DS3D_COMPILER_HAS_AVX2_FMA)
    set(_ds3d_simd_why "auto: the compiler rejects -mavx2 -mfma")
  elseif(CMAKE_CROSSCOMPILING)
    set(_ds3d_simd_why "auto: cross-compiling, the target CPU is unknown")
  else()
    set(CMAKE_REQUIRED_FLAGS "-mavx2 -mfma")
    check_cxx_source_runs([=[
      int main() {
        __builtin_cpu_init();
        return (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) ? 0 : 1;
      }]=] DS3D_HOST_RUNS_AVX2_FMA)
    unset(CMAKE_REQUIRED_FLAGS)
    if(DS3D_HOST_RUNS_AVX2_FMA)
      set(DS3D_SIMD_LEVEL avx2)
      set(_ds3d_simd_why "auto: compiler and build host support AVX2+FMA")
    else()
      set(_ds3d_simd_why "auto: the build host lacks AVX2 or FMA")
    endif()
  endif()
endif()
message(STATUS "ds3d SIMD level: ${DS3D_SIMD_LEVEL} (${_ds3d_simd_why})")

# GCC >= 12 reports false -Warray-bounds in Eigen's AVX packet paths for 3-vectors assigned into
# run-time-sized blocks (dead 4-wide branches; GCC PR 106247, Eigen report 2506), e.g. the comma
# initialiser `v4 << v3, s`. Those are not our bugs: the AVX build turns this one warning off
# (the `none` build keeps it, so real out-of-bounds accesses are still reported there).
set(DS3D_SIMD_WARNING_FLAGS_AVX2 "")
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_GREATER_EQUAL 12)
  set(DS3D_SIMD_WARNING_FLAGS_AVX2 -Wno-array-bounds)
endif()

# What ds3d::abi carries and ds3d_target_simd() applies.
set(DS3D_ABI_COMPILE_DEFINITIONS EIGEN_MAX_ALIGN_BYTES=16)
set(DS3D_ABI_COMPILE_OPTIONS "")
if(DS3D_SIMD_LEVEL STREQUAL "avx2")
  set(DS3D_ABI_COMPILE_OPTIONS ${DS3D_SIMD_FLAGS_AVX2})
endif()

# Applies the chosen SIMD flags to one of our compiled targets (PRIVATE: never propagated).
function(ds3d_target_simd target)
  target_compile_definitions(${target} PRIVATE ${DS3D_ABI_COMPILE_DEFINITIONS})
  if(DS3D_SIMD_LEVEL STREQUAL "avx2")
    target_compile_options(${target} PRIVATE ${DS3D_SIMD_FLAGS_AVX2} ${DS3D_SIMD_WARNING_FLAGS_AVX2})
  endif()
endfunction()
