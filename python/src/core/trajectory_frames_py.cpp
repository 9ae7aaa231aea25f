// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/eval/trajectory_frames.hpp. Trajectories cross as (n, 8) float64
// arrays (trajectory_util.hpp), transforms as 4x4 float64 matrices.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "../trajectory_util.hpp"
#include "ds3d/eval/trajectory_frames.hpp"

namespace py = pybind11;

using ds3d::py_traj::from_rows;
using ds3d::py_traj::Rows;
using ds3d::py_traj::to_rows;

void bind_trajectory_frames(py::module_& m) {
  m.def(
      "transform_trajectory",
      [](const Eigen::Ref<const Rows>& rows, const Eigen::Matrix4d& world_from,
         const Eigen::Matrix4d& body_to) {
        return to_rows(ds3d::transform_trajectory(from_rows(rows, "ds3d.transform_trajectory"),
                                                  Eigen::Isometry3d(world_from),
                                                  Eigen::Isometry3d(body_to)));
      },
      py::arg("trajectory"), py::arg("world_from"), py::arg("body_to"),
      "Every pose T of an (n, 8) trajectory replaced by world_from @ T @ body_to (4x4 rigid\n"
      "transforms: old world -> new world, new body -> old body). Raises ValueError for a\n"
      "transform that is not finite and rigid.");
  m.def(
      "bonn_marker_to_camera",
      [](const Eigen::Ref<const Rows>& rows) {
        return to_rows(ds3d::bonn_marker_to_camera(from_rows(rows, "ds3d.bonn_marker_to_camera")));
      },
      py::arg("trajectory"),
      "Camera poses from a Bonn RGB-D Dynamic groundtruth (marker poses) by the dataset's fixed\n"
      "transforms T_ros^-1 @ T @ T_ros @ T_m, T_m's rotation orthonormalised\n"
      "(include/ds3d/eval/trajectory_frames.hpp).");
  m.attr("BONN_DEPTH_SCALE_FACTOR") = ds3d::kBonnDepthScaleFactor;
}
