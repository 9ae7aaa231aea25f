// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Trajectories across the boundary: (n, 8) float64 rows timestamp tx ty tz qx qy qz qw (TUM
// columns, camera-to-world) <-> ds3d::Trajectory. Shared by trajectory_py and trajectory_plot_py.
#include <Eigen/Core>

#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"

namespace ds3d::py_traj {

using Rows = Eigen::Matrix<double, Eigen::Dynamic, 8, Eigen::RowMajor>;

/// Rows -> Trajectory; throws InvalidArgument naming `fn` and the row for a non-finite row.
inline Trajectory from_rows(const Eigen::Ref<const Rows>& a, const char* fn) {
  Trajectory t(static_cast<std::size_t>(a.rows()));
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    auto& p = t[static_cast<std::size_t>(i)];
    p.timestamp = a(i, 0);
    p.T_world_cam.translation() = Eigen::Vector3d(a(i, 1), a(i, 2), a(i, 3));
    DS3D_CHECK(a.row(i).allFinite(), fn, ": row ", i, " is not finite");
    p.T_world_cam.linear() = detail::tum_quaternion_to_matrix(a(i, 4), a(i, 5), a(i, 6), a(i, 7));
  }
  return t;
}

/// Trajectory -> rows.
inline Rows to_rows(const Trajectory& t) {
  Rows a(static_cast<Eigen::Index>(t.size()), 8);
  for (std::size_t i = 0; i < t.size(); ++i) {
    const Eigen::Quaterniond q(t[i].T_world_cam.linear());
    const Eigen::Vector3d x = t[i].T_world_cam.translation();
    a.row(static_cast<Eigen::Index>(i)) << t[i].timestamp, x.x(), x.y(), x.z(), q.x(), q.y(), q.z(),
        q.w();
  }
  return a;
}

}  // namespace ds3d::py_traj
