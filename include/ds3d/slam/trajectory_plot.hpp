// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file trajectory_plot.hpp
/// @brief A PNG a person wants to look at after an ATE run (compiled into ds3d::slam, OpenCV
/// drawing): left, the top view of the ground truth (grey) and the aligned estimate coloured by
/// its error; right, the error over time with the RMSE and the statistics, and the local ATE
/// per window (AteResult::windows, when evaluated with AteOptions::window > 0).

#include <filesystem>
#include <string>

#include <opencv2/core.hpp>

#include "ds3d/detail/abi_guard.hpp"
#include "ds3d/eval/trajectory.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"

namespace ds3d {

/// Options of render_ate_plot().
struct AtePlotOptions {
  int width = 1400;        ///< image width [px], >= 400
  int height = 640;        ///< image height [px], >= 300
  std::string title = {};  ///< first line of the header (e.g. the file names)
  void validate() const;   ///< throws ds3d::InvalidArgument
};

/// Draws the ATE plot. The top view is the plane of the two principal axes of the ground-truth
/// positions (for TUM's z-up mocap frame: the floor plane), equal scale on both axes.
/// @param gt     the ground truth (its whole path is drawn)
/// @param result evaluate_ate(gt, est) (matches give the aligned estimate and errors)
/// @param options image size and title
/// @return CV_8UC3 image
/// @throws ds3d::InvalidArgument for bad options or a result without matches.
[[nodiscard]] cv::Mat render_ate_plot(const Trajectory& gt, const AteResult& result,
                                      const AtePlotOptions& options = {});

/// render_ate_plot() written as PNG (temporary file + rename). @throws ds3d::IoError.
void write_ate_plot(const std::filesystem::path& path, const Trajectory& gt,
                    const AteResult& result, const AtePlotOptions& options = {});

}  // namespace ds3d
