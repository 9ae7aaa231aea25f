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

/// Throws InvalidArgument (ValueError) unless `obj` is an (N, 3) array-like of real numbers.
inline void check_points(const char* function, const pybind11::handle& obj) {
  const pybind11::array a = pybind11::array::ensure(obj);
  std::string desc = pybind11::str(pybind11::type::of(obj)).cast<std::string>();
  if (a) {
    const char kind = a.dtype().kind();
    if (a.ndim() == 2 && a.shape(1) == 3 && (kind == 'f' || kind == 'i' || kind == 'u')) return;
    desc = "array of dtype " + pybind11::str(a.dtype()).cast<std::string>() + " and shape (";
    for (pybind11::ssize_t i = 0; i < a.ndim(); ++i) {
      desc += (i ? ", " : "") + std::to_string(a.shape(i));
    }
    desc += ")";
  } else {
    PyErr_Clear();
  }
  throw InvalidArgument(std::string(function) +
                        ": points must be an (N, 3) float32 or float64 array (got " + desc + ")");
}

/// Defines the public `name(points, ...)`: checks `points` (ValueError with its shape and dtype
/// instead of pybind11's TypeError), then forwards everything to the typed overloads that were
/// registered as `impl` (float32 and float64 without a copy, anything else converted).
inline void def_checked(pybind11::module_& m, const char* name, const char* impl,
                        const std::string& doc) {
  const std::string fn = std::string("ds3d.") + name;
  m.def(
      name,
      [m, fn, impl](const pybind11::args& args, const pybind11::kwargs& kwargs) {
        pybind11::object points;
        if (!args.empty()) {
          points = args[0];
        } else if (kwargs.contains("points")) {
          points = kwargs["points"];
        }
        check_points(fn.c_str(), points);
        return m.attr(impl)(*args, **kwargs);
      },
      doc.c_str());
}

}  // namespace ds3d::py_util
