// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file ds3d.hpp
/// @brief Umbrella header for the header-only core (`ds3d::core`: Eigen + nanoflann only):
/// point traits, preprocessing, HDBSCAN, the dynamic-feature filter and detections, trajectory
/// I/O and metrics. The HTx detector (`ds3d::htx`, include/ds3d/htx/) and the SLAM front-end
/// (`ds3d::slam`, OpenCV + Ceres, include/ds3d/slam/) have their own headers.

#include "ds3d/box3.hpp"
#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/cluster/hdbscan_predict.hpp"
#include "ds3d/dynamic/detections.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_formats.hpp"
#include "ds3d/eval/trajectory_frames.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "ds3d/preprocess/preprocess.hpp"
#include "ds3d/preprocess/radius_outlier.hpp"
#include "ds3d/preprocess/ransac_plane.hpp"
#include "ds3d/preprocess/rgbd.hpp"
#include "ds3d/preprocess/voxel_grid.hpp"
#include "ds3d/version.hpp"
