// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Small helpers shared by the preprocessing bindings: std::vector -> numpy copies and a clear
// ValueError for arrays that are not (N, 3) float32/float64.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstring>
#include <string>
#include <vector>

#include "ds3d/errors.hpp"

namespace ds3d::py_util {

/// 1-D numpy copy of a vector.
template <class T>
pybind11::array_t<T> to_numpy(const std::vector<T>& v) {
  pybind11::array_t<T> a(static_cast<pybind11::ssize_t>(v.size()));
  if (!v.empty()) std::memcpy(a.mutable_data(), v.data(), v.size() * sizeof(T));
  return a;
}

/// Fallback overload body: always throws InvalidArgument (ValueError) describing `obj`.
[[noreturn]] inline void reject_points(const char* function, const pybind11::object& obj) {
  std::string desc = pybind11::str(pybind11::type::of(obj)).cast<std::string>();
  if (pybind11::isinstance<pybind11::array>(obj)) {
    const auto a = pybind11::reinterpret_borrow<pybind11::array>(obj);
    desc = "array of dtype " + pybind11::str(a.dtype()).cast<std::string>() + " and shape (";
    for (pybind11::ssize_t i = 0; i < a.ndim(); ++i) {
      desc += (i ? ", " : "") + std::to_string(a.shape(i));
    }
    desc += ")";
  }
  throw InvalidArgument(std::string(function) +
                        ": points must be an (N, 3) float32 or float64 array (got " + desc + ")");
}

}  // namespace ds3d::py_util
