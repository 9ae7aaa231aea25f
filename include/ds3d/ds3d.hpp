// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file ds3d.hpp
/// @brief Umbrella header for the header-only core (`ds3d::core`: Eigen + nanoflann only).
/// The SLAM front-end (OpenCV + Ceres, target `ds3d::slam`) has its own headers.

#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/preprocess.hpp"
#include "ds3d/radius_outlier.hpp"
#include "ds3d/ransac_plane.hpp"
#include "ds3d/rgbd.hpp"
#include "ds3d/version.hpp"
#include "ds3d/voxel_grid.hpp"
