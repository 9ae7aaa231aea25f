// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/part_a2_targets.hpp (see that header for the documentation).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <vector>

#include "ds3d/htx/part_a2_targets.hpp"

namespace py = pybind11;

void bind_part_a2_targets(py::module_& m) {
  m.def(
      "part_a2_targets",
      [](const Eigen::Ref<const ds3d::Points3f>& xyz,
         const Eigen::Ref<
             const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& boxes,
         double extra_width) {
        DS3D_CHECK(boxes.rows() == 0 || boxes.cols() == 7,
                   "ds3d.part_a2_targets: boxes must have shape (m, 7) (got (", boxes.rows(), ", ",
                   boxes.cols(), "))");
        std::vector<ds3d::Box3> bx(static_cast<std::size_t>(boxes.rows()));
        for (Eigen::Index k = 0; k < boxes.rows(); ++k) {
          auto& b = bx[static_cast<std::size_t>(k)];
          b.centre = boxes.row(k).head<3>().transpose();
          b.size = boxes.row(k).segment<3>(3).transpose();
          b.yaw = boxes(k, 6);
        }
        ds3d::PartTargets t;
        {
          py::gil_scoped_release release;
          t = ds3d::part_a2_targets(xyz, bx, {.extra_width = extra_width});
        }
        py::dict d;
        d["label"] =
            py::array_t<std::int8_t>(static_cast<py::ssize_t>(t.label.size()), t.label.data());
        d["box_index"] = py::array_t<std::int32_t>(static_cast<py::ssize_t>(t.box_index.size()),
                                                   t.box_index.data());
        d["part"] = ds3d::Points3f(t.part);
        d["num_non_finite"] = t.num_non_finite;
        return d;
      },
      py::arg("xyz"), py::arg("boxes"), py::arg("extra_width") = 0.2,
      "Part-A2 part-location targets (include/ds3d/part_a2_targets.hpp). xyz (n, 3) float32, "
      "boxes\n"
      "(m, 7) float32 (cx, cy, cz, dx, dy, dz, yaw; yaw from +X towards -Y). Returns a dict with\n"
      "label int8 (1 fg, 0 bg, -1 ignore), box_index int32, part (n, 3) float32, num_non_finite.");
}
