# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# ds3d_enable_avx2(target source...): compiles the given sources of `target` with -mavx2 -mfma
# according to DS3D_AVX2 (AUTO/ON/OFF). Eigen's alignment is pinned to 16 bytes in those sources
# so that objects and heap blocks stay ABI-compatible with the rest of the program (Eigen would
# otherwise use 32-byte alignment and its own aligned malloc under AVX, and a matrix allocated in
# one translation unit and freed in another would corrupt the heap).
include(CheckCXXSourceRuns)
function(ds3d_enable_avx2 target)
  set(sources ${ARGN})
  if(DS3D_AVX2 STREQUAL "OFF" OR NOT CMAKE_SYSTEM_PROCESSOR MATCHES "x86_64|AMD64|amd64")
    return()
  endif()
  if(DS3D_AVX2 STREQUAL "AUTO")
    if(NOT DEFINED DS3D_HOST_HAS_AVX2)
      set(CMAKE_REQUIRED_QUIET ON)
      check_cxx_source_runs("int main() { __builtin_cpu_init();
        return (__builtin_cpu_supports(\"avx2\") && __builtin_cpu_supports(\"fma\")) ? 0 : 1; }"
        DS3D_HOST_HAS_AVX2)
    endif()
    if(NOT DS3D_HOST_HAS_AVX2)
      message(STATUS "ds3d: AVX2/FMA not available on this CPU: baseline x86-64 code for ${sources}")
      return()
    endif()
  endif()
  message(STATUS "ds3d: AVX2 + FMA enabled for ${sources} (DS3D_AVX2=${DS3D_AVX2})")
  set_source_files_properties(${sources} TARGET_DIRECTORY ${target} PROPERTIES
    COMPILE_OPTIONS "-mavx2;-mfma"
    COMPILE_DEFINITIONS "EIGEN_MAX_ALIGN_BYTES=16;EIGEN_MAX_STATIC_ALIGN_BYTES=16")
endfunction()
