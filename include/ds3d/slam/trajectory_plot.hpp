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
#include <vector>

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

/// One estimate of render_multi_ate_plot().
struct AtePlotEstimate {
  std::string label;  ///< legend text (e.g. the file name; long ones keep their last 60 chars)
  AteResult result;   ///< evaluate_ate(gt, estimate)
};

/// Draws several estimates against one ground truth, evo-style. Left, the top view (the plane
/// of the two principal axes of the ground-truth positions, as render_ate_plot()): the ground
/// truth grey, each aligned estimate coloured by its error on one scale shared by all (0 .. the
/// largest error of any estimate), over a wider line in the estimate's own colour and with its
/// number `[k]` at its end; beside it the colour bar of that error scale [m]. Right, each
/// estimate's error over time in its own colour with its RMSE as a thin line. The header lists
/// every estimate (number, label, pairs and statistics) in its colour. Local-ATE windows are not
/// drawn.
/// @param gt        the ground truth (its whole path is drawn)
/// @param estimates 1 to 10 estimates, each with a result with matches
/// @param options   image size (height >= 200 px + 18 px per estimate + 34 px) and title
/// @return CV_8UC3 image of options.width x options.height
/// @throws ds3d::InvalidArgument for bad options, no or too many estimates, a result without
///   matches or with non-finite statistics.
[[nodiscard]] cv::Mat render_multi_ate_plot(const Trajectory& gt,
                                            const std::vector<AtePlotEstimate>& estimates,
                                            const AtePlotOptions& options = {});

/// render_multi_ate_plot() written as PNG (temporary file + rename). @throws ds3d::IoError.
void write_multi_ate_plot(const std::filesystem::path& path, const Trajectory& gt,
                          const std::vector<AtePlotEstimate>& estimates,
                          const AtePlotOptions& options = {});

}  // namespace ds3d
