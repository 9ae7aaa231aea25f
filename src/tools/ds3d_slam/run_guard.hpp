// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d-slam's safeguards: output paths checked up front, SIGINT/SIGTERM, input warnings.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "ds3d/slam/config.hpp"
#include "ds3d/slam/dataset.hpp"

namespace ds3d_slam_tool {

/// One output file (--out, --stats, ...) given on the command line.
struct OutputPath {
  const char* flag;            ///< "--out"
  std::filesystem::path path;  ///< empty = not requested
};

/// Throws ds3d::IoError naming the flag and the path when a requested file cannot be written
/// there (its folder is missing or not writable, or the path is a folder), or when an output
/// folder (--viz, --dynamic-out) names something that is not a folder or cannot be created.
/// Creates the requested output folders (with their parents).
void check_output_paths(const std::vector<OutputPath>& files,
                        const std::vector<OutputPath>& folders);

/// Installs the SIGINT/SIGTERM handler: the first signal asks the run to stop after the frames
/// already read (the outputs are then written as usual); a second one ends the process at once.
void install_stop_handler();
/// The signal that asked to stop (SIGINT, SIGTERM), 0 if none.
[[nodiscard]] int stop_signal() noexcept;
/// "SIGINT", "SIGTERM" or "signal N".
[[nodiscard]] std::string signal_name(int sig);

/// Counts of suspicious input found before the run (each also printed once as a warning).
struct InputWarnings {
  std::size_t duplicate_rgb_stamps = 0;
  std::size_t duplicate_depth_stamps = 0;
  std::size_t unassociated_rgb = 0;
  std::size_t large_gaps = 0;
  std::size_t frames_without_detections = 0;  ///< frames no file:PATH source has a line for
  std::size_t weights_without_checksum = 0;   ///< 1 when the htx weights carry no checksum
};

/// Prints one warning line to stderr per kind of problem in the dataset's lists and in the
/// file:PATH detections of `config` over the `frames` frames from frame `first` on.
/// @throws ds3d::IoError naming the file when a detections file matches none of the frames.
[[nodiscard]] InputWarnings check_inputs(const ds3d::RgbdDataset& ds, std::size_t first,
                                         std::size_t frames, const ds3d::slam::SlamConfig& config);

/// The weights that the htx source of `config` loads, when it names one ("" otherwise).
[[nodiscard]] std::filesystem::path htx_weights(const ds3d::slam::SlamConfig& config);

}  // namespace ds3d_slam_tool
