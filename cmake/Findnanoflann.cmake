# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Finds nanoflann (header-only). Debian's libnanoflann-dev ships no CMake package, so this module
# looks for the header and defines the imported target nanoflann::nanoflann.
find_package(nanoflann CONFIG QUIET NO_MODULE)
if(TARGET nanoflann::nanoflann)
  set(nanoflann_FOUND TRUE)
  return()
endif()
find_path(nanoflann_INCLUDE_DIR nanoflann.hpp)
if(nanoflann_INCLUDE_DIR)
  file(STRINGS ${nanoflann_INCLUDE_DIR}/nanoflann.hpp _nf_ver REGEX "#define NANOFLANN_VERSION ")
  string(REGEX REPLACE ".*0x([0-9a-fA-F])([0-9a-fA-F])([0-9a-fA-F]).*" "\\1.\\2.\\3" nanoflann_VERSION "${_nf_ver}")
endif()
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(nanoflann REQUIRED_VARS nanoflann_INCLUDE_DIR VERSION_VAR nanoflann_VERSION)
if(nanoflann_FOUND AND NOT TARGET nanoflann::nanoflann)
  add_library(nanoflann::nanoflann INTERFACE IMPORTED)
  set_target_properties(nanoflann::nanoflann PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${nanoflann_INCLUDE_DIR}")
endif()
mark_as_advanced(nanoflann_INCLUDE_DIR)
