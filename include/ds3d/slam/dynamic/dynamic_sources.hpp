// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file dynamic_sources.hpp
/// @brief The dynamic-object sources by name (ds3d::slam; OpenCV): make_dynamic_source builds the
/// source of a `--dynamic` value, with the default HTx weights lookup. Includes every source's
/// header: FileSource (file_source.hpp), MaskSource (mask_source.hpp), HdbscanMasker (hdbscan_masker.hpp), HtxSource
/// (htx_source.hpp), CompositeSource and MotionGatedSource (combinators.hpp),
/// GeometricMotionSource (geometric_motion.hpp), and image_boxes / keypoint_array (boxes.hpp).

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "ds3d/slam/dynamic/boxes.hpp"
#include "ds3d/slam/dynamic/combinators.hpp"
#include "ds3d/slam/dynamic/file_source.hpp"
#include "ds3d/slam/dynamic/mask_source.hpp"
#include "ds3d/slam/dynamic/geometric_motion.hpp"
#include "ds3d/slam/dynamic/hdbscan_masker.hpp"
#include "ds3d/slam/dynamic/htx_source.hpp"
#include "ds3d/slam/dynamic/objects.hpp"

namespace ds3d::slam {

/// Where the default HTx weights are looked for, in order: `<source tree>/models/NAME` (the
/// compile-time DS3D_SOURCE_DIR), `<install prefix>/share/ds3d/models/NAME` (configure-time
/// prefix), and `<directory of the running executable>/../share/ds3d/models/NAME` (a relocated
/// install). NAME is kDefaultHtxWeights.
[[nodiscard]] std::vector<std::filesystem::path> default_weights_candidates();
/// File name of the default weights.
inline constexpr const char* kDefaultHtxWeights = "htx_lite_fast.safetensors";
/// The first existing default_weights_candidates() entry.
/// @throws ds3d::IoError naming every path tried when none exists.
[[nodiscard]] std::filesystem::path find_default_weights();

/// Options of make_dynamic_source for the sources that take any.
struct DynamicSourceOptions {
  std::filesystem::path weights{};  ///< htx weights; empty = find_default_weights()
  HtxSourceParams htx{};            ///< htx parameters (detect_every, min_score, ...)
  GeometricMotionParams geometric{};  ///< geometric parameters
  FileSourceParams file{};          ///< file:PATH parameters
  MotionGateParams gate{};          ///< the gate of SlamConfig::gate (config.hpp)
};

/// Builds the source named by a `--dynamic` option value: "none", "file:PATH" (FileSource with
/// options.file; the rest of the string is the path), "mask:DIR" (MaskSource with
/// options.file.max_dt: per-frame mask images), "geometric" (GeometricMotionSource with
/// options.geometric), "htx" (HtxSource, weights and parameters from `options`), or "A+B" with A
/// and B any of these but none (CompositeSource: A, then B, each on the whole frame), e.g.
/// "htx+geometric" or "file:dets.jsonl+geometric": a path ends at the first '+' followed by a
/// source name (geometric, htx, file:, mask:) unless the whole rest names an existing file or
/// folder. Gating by the geometric source (MotionGatedSource) is a separate setting:
/// make_dynamic_source(const SlamConfig&) in config.hpp, `ds3d-slam --gate motion|evidence`.
/// @throws ds3d::InvalidArgument for an unknown name or bad options; ds3d::IoError for an
///   unreadable file or weights file (naming the path).
[[nodiscard]] std::shared_ptr<DynamicObjectSource> make_dynamic_source(
    const std::string& spec, const DynamicSourceOptions& options = {});

}  // namespace ds3d::slam
