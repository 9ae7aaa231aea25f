// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The heavy core entry points for targets linking ds3d::core_separate (compiled with their flags).
#if !defined(DS3D_CORE_SEPARATE)
#error \
    "ds3d_core_separate.cpp is added by the CMake target ds3d::core_separate, which defines DS3D_CORE_SEPARATE"
#endif
#define DS3D_CORE_IMPLEMENTATION

#include <vector>

#include <Eigen/Core>

#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"

namespace ds3d {
template VoxelGridResult voxel_grid<Points3f>(const Points3f&, const VoxelGridParams&);
template VoxelGridResult voxel_grid<Eigen::Ref<const Points3f>>(const Eigen::Ref<const Points3f>&,
                                                                const VoxelGridParams&);
template VoxelGridResult voxel_grid<std::vector<Eigen::Vector3f>>(
    const std::vector<Eigen::Vector3f>&, const VoxelGridParams&);
}  // namespace ds3d
