// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Conversions from DynamicObjects and ORB features to the dynamic filter's inputs.
#pragma once
/// @file boxes.hpp
/// @brief image_boxes (DynamicObjects -> ImageBox list) and keypoint_array (OrbFeatures -> (u, v,
/// z) rows), the inputs of DynamicFeatureFilter (ds3d::slam; OpenCV).

#include <vector>

#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/slam/dynamic/objects.hpp"
#include "ds3d/slam/orb_features.hpp"

namespace ds3d::slam {

/// The image boxes of `objects`: its 2-D boxes (with their scores, 1 when absent) and its 3-D
/// boxes projected with `camera` (with their depth ranges); boxes wholly outside the image or
/// behind the camera are left out.
/// @throws ds3d::InvalidArgument when `scores` is neither empty nor one per 2-D box.
[[nodiscard]] std::vector<ImageBox> image_boxes(const DynamicObjects& objects,
                                                const PinholeCamera& camera);

/// Keypoints of `features` as (u, v, z) rows: raw pixel, and the depth of `depth` at the rounded
/// pixel (0 = none) when `depth` is a CV_16UC1 image of the camera size, else features.depth.
[[nodiscard]] Keypoints3f keypoint_array(const OrbFeatures& features, const cv::Mat& depth,
                                         const PinholeCamera& camera);

}  // namespace ds3d::slam
