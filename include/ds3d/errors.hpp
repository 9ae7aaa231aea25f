// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file errors.hpp
/// @brief ds3d's exception types and the DS3D_CHECK / DS3D_ASSERT macros (STYLE.md §5).
///
/// All exceptions derive from the standard ones so that pybind11 translates them without extra
/// code: InvalidArgument (std::invalid_argument) becomes Python's ValueError; IoError and
/// NumericalError (std::runtime_error) become RuntimeError.

#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace ds3d {

/// A parameter or input value is outside its documented range. Message names the function,
/// the parameter and the offending value, e.g. `ds3d::voxel_grid: leaf_size must be > 0 (got
/// -0.1)`.
class InvalidArgument : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A file could not be read or written, or its content is malformed (names the file or tensor).
class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A computation could not produce a finite, meaningful result (e.g. a singular system).
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace detail {

/// Concatenates any streamable values into one string (used to build error messages).
template <class... Args>
[[nodiscard]] std::string concat(Args&&... args) {
  std::ostringstream os;
  os.precision(17);
  (os << ... << std::forward<Args>(args));
  return os.str();
}

}  // namespace detail
}  // namespace ds3d

/// Always-on check at API boundaries: throws ds3d::InvalidArgument with the streamed message.
/// Usage: `DS3D_CHECK(leaf > 0, "ds3d::voxel_grid: leaf_size must be > 0 (got ", leaf, ")");`
#define DS3D_CHECK(cond, ...)                                             \
  do {                                                                    \
    if (!(cond)) {                                                        \
      throw ::ds3d::InvalidArgument(::ds3d::detail::concat(__VA_ARGS__)); \
    }                                                                     \
  } while (false)

/// Like DS3D_CHECK but throws the given exception type (IoError, NumericalError, ...).
#define DS3D_CHECK_AS(ExceptionType, cond, ...)                 \
  do {                                                          \
    if (!(cond)) {                                              \
      throw ExceptionType(::ds3d::detail::concat(__VA_ARGS__)); \
    }                                                           \
  } while (false)

/// Internal invariant for hot loops; compiled out under NDEBUG.
#ifdef NDEBUG
#define DS3D_ASSERT(cond) ((void)0)
#else
#include <cassert>
#define DS3D_ASSERT(cond) assert(cond)
#endif
