// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Bindings for include/ds3d/voxel_grid.hpp: ds3d.voxel_grid(points, leaf_size, num_threads=1).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "ds3d/preprocess/voxel_grid.hpp"
#include "numpy_util.hpp"

namespace py = pybind11;

namespace {

/// leaf_size: a number (cubic voxels) or a (dx, dy, dz) sequence.
ds3d::LeafSize to_leaf(const py::object& leaf) {
  if (py::isinstance<py::float_>(leaf) || py::isinstance<py::int_>(leaf)) {
    return {leaf.cast<double>()};
  }
  if (py::isinstance<py::sequence>(leaf) && !py::isinstance<py::str>(leaf)) {
    const auto seq = leaf.cast<py::sequence>();
    DS3D_CHECK(seq.size() == 3, "ds3d.voxel_grid: leaf_size must be a number or (dx, dy, dz) (got ",
               seq.size(), " values)");
    return {seq[0].cast<double>(), seq[1].cast<double>(), seq[2].cast<double>()};
  }
  throw ds3d::InvalidArgument("ds3d.voxel_grid: leaf_size must be a number or (dx, dy, dz) (got " +
                              py::str(leaf).cast<std::string>() + ")");
}

template <class Ref>
ds3d::VoxelGridResult run(const Ref& points, const py::object& leaf, int num_threads,
                          std::uint32_t min_points) {
  ds3d::VoxelGridParams p;
  p.leaf_size = to_leaf(leaf);
  p.num_threads = num_threads;
  p.min_points = min_points;
  const py::gil_scoped_release release;
  return ds3d::voxel_grid(points, p);
}

}  // namespace

void bind_voxel_grid(py::module_& m) {
  py::class_<ds3d::VoxelGridResult>(m, "VoxelGridResult",
                                    "Output of voxel_grid (include/ds3d/voxel_grid.hpp).")
      .def_readonly("centroids", &ds3d::VoxelGridResult::centroids, "(M, 3) float32 centroids")
      .def_readonly("keys", &ds3d::VoxelGridResult::keys, "(M, 3) int64 voxel keys, sorted")
      .def_property_readonly(
          "counts",
          [](const ds3d::VoxelGridResult& r) { return ds3d::py_util::to_numpy(r.counts); },
          "(M,) uint32 member counts")
      .def_property_readonly(
          "representative",
          [](const ds3d::VoxelGridResult& r) { return ds3d::py_util::to_numpy(r.representative); },
          "(M,) uint32 input index of the member nearest each centroid")
      .def_readonly("num_non_finite", &ds3d::VoxelGridResult::num_non_finite)
      .def_readonly("num_dropped", &ds3d::VoxelGridResult::num_dropped)
      .def("__repr__", [](const ds3d::VoxelGridResult& r) {
        return "<VoxelGridResult voxels=" + std::to_string(r.centroids.rows()) + ">";
      });
  const char* doc =
      "Voxel-grid centroids on an origin-anchored grid (see include/ds3d/voxel_grid.hpp).\n"
      "points: (N, 3) float32 or float64; leaf_size: metres, a number or (dx, dy, dz).\n"
      "Non-finite rows are ignored. Raises ValueError on bad parameters.";
  m.def("_voxel_grid", &run<Eigen::Ref<const ds3d::Points3f>>, py::arg("points").noconvert(),
        py::arg("leaf_size"), py::arg("num_threads") = 1, py::arg("min_points") = 1, doc);
  m.def("_voxel_grid", &run<Eigen::Ref<const ds3d::Points3d>>, py::arg("points").noconvert(),
        py::arg("leaf_size"), py::arg("num_threads") = 1, py::arg("min_points") = 1, doc);
  m.def("_voxel_grid", &run<Eigen::Ref<const ds3d::Points3d>>, py::arg("points"),
        py::arg("leaf_size"), py::arg("num_threads") = 1, py::arg("min_points") = 1, doc);
  ds3d::py_util::def_checked(m, "voxel_grid", "_voxel_grid", doc);
  m.def("release_voxel_grid_scratch", &ds3d::release_voxel_grid_scratch,
        "Frees the calling thread's cached voxel_grid scratch (kept between calls, at most\n"
        "64 MiB per thread); returns the bytes released (0 when there was none).");
}
