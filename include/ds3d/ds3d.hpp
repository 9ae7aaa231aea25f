// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file ds3d.hpp
/// @brief Umbrella header for the header-only core (`ds3d::core`: Eigen + nanoflann only).
/// The SLAM front-end (OpenCV + Ceres, target `ds3d::slam`) has its own headers.

#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/preprocess/preprocess.hpp"
#include "ds3d/preprocess/radius_outlier.hpp"
#include "ds3d/preprocess/ransac_plane.hpp"
#include "ds3d/preprocess/rgbd.hpp"
#include "ds3d/version.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"
