# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Warnings for our own compiled, test and bench targets (never INTERFACE ones, STYLE.md §10).
function(ds3d_target_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wconversion -Wshadow)
  if(DS3D_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
