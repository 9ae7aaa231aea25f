// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// MaskSource: per-frame dynamic masks read from a folder of images.
#pragma once
/// @file mask_source.hpp
/// @brief The `mask:DIR` dynamic-object source (ds3d::slam; OpenCV): per-pixel masks of an
/// external segmenter, run offline (or the ground-truth masks that ds3d-synth writes).

#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "ds3d/camera.hpp"
#include "ds3d/slam/dynamic/objects.hpp"

namespace ds3d::slam {

/// The `mask:DIR` source: DIR holds one single-channel image per frame, named by its timestamp
/// as in TUM lists (`1700000000.033333.png`), non-zero = dynamic. detect() returns the mask of
/// the frame nearest in time within `max_dt` as DynamicObjects::pixel_mask (the masker then
/// flags every keypoint on it); a frame without a mask gets none.
/// @note The folder is listed once in the constructor; each frame reads one image.
class MaskSource final : public DynamicObjectSource {
 public:
  /// @param dir     folder of mask images (PNG or any format OpenCV reads)
  /// @param max_dt  largest frame ↔ mask timestamp difference [s], finite, >= 0
  /// @throws ds3d::IoError when `dir` is not a folder or holds no image named by a timestamp;
  ///         ds3d::InvalidArgument for a bad max_dt
  explicit MaskSource(const std::filesystem::path& dir, double max_dt = 0.02);
  /// @throws ds3d::IoError when the matched image cannot be read or its size is not the camera's
  DynamicObjects detect(const FrameInput& frame, const PinholeCamera& camera) override;
  [[nodiscard]] std::string name() const override { return "mask"; }
  /// Frames detect() found a mask for so far.
  [[nodiscard]] std::size_t num_matched() const noexcept { return matched_; }
  /// Frames detect() found no mask for (within max_dt) so far.
  [[nodiscard]] std::size_t num_unmatched() const noexcept { return unmatched_; }

 private:
  std::vector<std::pair<double, std::filesystem::path>> masks_;  // sorted by timestamp
  double max_dt_;
  std::size_t matched_ = 0;
  std::size_t unmatched_ = 0;
};

}  // namespace ds3d::slam
