// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/trajectory.hpp and trajectory_metrics.hpp. A trajectory crosses the
// boundary as a float64 array of shape (n, 8): timestamp tx ty tz qx qy qz qw (TUM columns).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

#include "../trajectory_util.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"

namespace py = pybind11;

using ds3d::py_traj::from_rows;
using ds3d::py_traj::Rows;
using ds3d::py_traj::to_rows;

void bind_trajectory(py::module_& m) {
  py::class_<ds3d::ErrorStats>(m, "ErrorStats", "rmse, mean, median, std (population), min, max.")
      .def_readonly("rmse", &ds3d::ErrorStats::rmse)
      .def_readonly("mean", &ds3d::ErrorStats::mean)
      .def_readonly("median", &ds3d::ErrorStats::median)
      .def_readonly("std", &ds3d::ErrorStats::std)
      .def_readonly("min", &ds3d::ErrorStats::min)
      .def_readonly("max", &ds3d::ErrorStats::max)
      .def("__repr__", [](const ds3d::ErrorStats& s) {
        return "ErrorStats(rmse=" + std::to_string(s.rmse) + ", mean=" + std::to_string(s.mean) +
               ", median=" + std::to_string(s.median) + ", max=" + std::to_string(s.max) + ")";
      });

  m.def(
      "read_tum_trajectory",
      [](const std::string& path, bool keep_zero_quaternion) {
        return to_rows(
            ds3d::read_tum_file(path, {.keep_zero_quaternion = keep_zero_quaternion}).trajectory);
      },
      py::arg("path"), py::arg("keep_zero_quaternion") = false,
      "Reads a TUM trajectory as an (n, 8) array [t tx ty tz qx qy qz qw], sorted, unique stamps.\n"
      "Rules of the TUM scripts (include/ds3d/trajectory.hpp). Raises RuntimeError on bad files.");
  m.def(
      "write_tum_trajectory",
      [](const std::string& path, const Eigen::Ref<const Rows>& rows) {
        ds3d::write_tum_trajectory(path, from_rows(rows, "ds3d.write_tum_trajectory"));
      },
      py::arg("path"), py::arg("trajectory"),
      "Writes an (n, 8) array as a TUM file (temporary file + rename).");

  py::class_<ds3d::AteWindow>(m, "AteWindow", "One window of the local ATE (evaluate_ate window=).")
      .def_readonly("start", &ds3d::AteWindow::start, "ground-truth stamp of the first pair [s]")
      .def_readonly("end", &ds3d::AteWindow::end, "ground-truth stamp of the last pair [s]")
      .def_readonly("pairs", &ds3d::AteWindow::pairs)
      .def_readonly("rmse", &ds3d::AteWindow::rmse, "[m], the window aligned on its own")
      .def("__repr__", [](const ds3d::AteWindow& w) {
        return "AteWindow(start=" + std::to_string(w.start) + ", end=" + std::to_string(w.end) +
               ", pairs=" + std::to_string(w.pairs) + ", rmse=" + std::to_string(w.rmse) + ")";
      });

  py::class_<ds3d::AteResult>(m, "AteResult",
                              "evaluate_ate() result (include/ds3d/trajectory_metrics.hpp).")
      .def_readonly("compared_pose_pairs", &ds3d::AteResult::compared_pose_pairs)
      .def_readonly("rmse", &ds3d::AteResult::rmse)
      .def_readonly("mean", &ds3d::AteResult::mean)
      .def_readonly("median", &ds3d::AteResult::median)
      .def_readonly("std", &ds3d::AteResult::std)
      .def_readonly("min", &ds3d::AteResult::min)
      .def_readonly("max", &ds3d::AteResult::max)
      .def_readonly("rotation", &ds3d::AteResult::rotation)
      .def_readonly("translation", &ds3d::AteResult::translation)
      .def_readonly("scale", &ds3d::AteResult::scale_factor)
      .def_readonly("windows", &ds3d::AteResult::windows,
                    "list of AteWindow (window > 0), in time order")
      .def_readonly("worst_window_rmse", &ds3d::AteResult::worst_window_rmse, "[m]; 0 if none")
      .def_readonly("num_short_windows", &ds3d::AteResult::num_short_windows,
                    "windows skipped for holding 1 or 2 pairs")
      .def_property_readonly(
          "matches",
          [](const ds3d::AteResult& r) {
            // (k, 9): t_gt t_est gt_xyz est_aligned_xyz... error last
            Eigen::Matrix<double, Eigen::Dynamic, 9, Eigen::RowMajor> a(
                static_cast<Eigen::Index>(r.matches.size()), 9);
            for (std::size_t i = 0; i < r.matches.size(); ++i) {
              const auto& x = r.matches[i];
              a.row(static_cast<Eigen::Index>(i)) << x.t_gt, x.t_est, x.p_gt.x(), x.p_gt.y(),
                  x.p_gt.z(), x.p_est.x(), x.p_est.y(), x.p_est.z(), x.error;
            }
            return a;
          },
          "(k, 9) array: t_gt t_est gt_x gt_y gt_z est_x est_y est_z error "
          "(estimate aligned)")
      .def("__repr__", [](const ds3d::AteResult& r) {
        return "AteResult(pairs=" + std::to_string(r.compared_pose_pairs) +
               ", rmse=" + std::to_string(r.rmse) + " m)";
      });
  m.def(
      "evaluate_ate",
      [](const Eigen::Ref<const Rows>& gt, const Eigen::Ref<const Rows>& est, double max_difference,
         double offset, double scale, const std::string& align, double window) {
        const ds3d::AteOptions o{max_difference, offset, scale, ds3d::parse_alignment(align),
                                 window};
        const auto g = from_rows(gt, "ds3d.evaluate_ate");
        const auto e = from_rows(est, "ds3d.evaluate_ate");
        py::gil_scoped_release release;
        return ds3d::evaluate_ate(g, e, o);
      },
      py::arg("gt"), py::arg("est"), py::arg("max_difference") = 0.02, py::arg("offset") = 0.0,
      py::arg("scale") = 1.0, py::arg("align") = "se3", py::arg("window") = 0.0,
      "ATE exactly as the TUM evaluate_ate.py; align: 'se3' (default), 'sim3' or 'none'.\n"
      "window > 0 [s]: also the local ATE, pairs cut into windows of ground-truth time, each\n"
      "aligned on its own (result.windows, result.worst_window_rmse).");

  py::class_<ds3d::RpeResult>(m, "RpeResult",
                              "evaluate_rpe() result (include/ds3d/trajectory_metrics.hpp).")
      .def_readonly("compared_pose_pairs", &ds3d::RpeResult::compared_pose_pairs)
      .def_readonly("translational", &ds3d::RpeResult::translational, "[m]")
      .def_readonly("rotational", &ds3d::RpeResult::rotational, "[deg]")
      .def_readonly("rotational_rad", &ds3d::RpeResult::rotational_rad, "[rad]")
      .def_readonly("subsampled", &ds3d::RpeResult::subsampled)
      .def_property_readonly(
          "pairs",
          [](const ds3d::RpeResult& r) {
            Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor> a(
                static_cast<Eigen::Index>(r.pairs.size()), 6);
            for (std::size_t i = 0; i < r.pairs.size(); ++i) {
              const auto& p = r.pairs[i];
              a.row(static_cast<Eigen::Index>(i)) << p.t_est0, p.t_est1, p.t_gt0, p.t_gt1,
                  p.trans_error, p.rot_error_rad;
            }
            return a;
          },
          "(k, 6) array: t_est0 t_est1 t_gt0 t_gt1 trans_error_m rot_error_rad");
  m.def(
      "evaluate_rpe",
      [](const Eigen::Ref<const Rows>& gt, const Eigen::Ref<const Rows>& est, double delta,
         const std::string& delta_unit, bool fixed_delta, std::size_t max_pairs, double offset,
         double scale, const std::string& convention, std::uint64_t seed) {
        ds3d::RpeOptions o;
        o.delta = delta;
        o.delta_unit = ds3d::parse_delta_unit(delta_unit);
        o.fixed_delta = fixed_delta;
        o.max_pairs = max_pairs;
        o.offset = offset;
        o.scale = scale;
        DS3D_CHECK(convention == "tum" || convention == "evo",
                   "ds3d.evaluate_rpe: convention must be 'tum' or 'evo' (got '", convention, "')");
        o.convention = convention == "tum" ? ds3d::RpeConvention::kTum : ds3d::RpeConvention::kEvo;
        o.seed = seed;
        const auto g = from_rows(gt, "ds3d.evaluate_rpe");
        const auto e = from_rows(est, "ds3d.evaluate_rpe");
        py::gil_scoped_release release;
        return ds3d::evaluate_rpe(g, e, o);
      },
      py::arg("gt"), py::arg("est"), py::arg("delta") = 1.0, py::arg("delta_unit") = "s",
      py::arg("fixed_delta") = true, py::arg("max_pairs") = 10000, py::arg("offset") = 0.0,
      py::arg("scale") = 1.0, py::arg("convention") = "tum", py::arg("seed") = 1,
      "RPE exactly as the TUM evaluate_rpe.py --fixed_delta; delta_unit: s, f, m, rad, deg.");
}
