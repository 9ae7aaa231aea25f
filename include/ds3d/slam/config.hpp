// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file config.hpp
/// @brief One configuration surface for a SLAM run (ds3d::slam; OpenCV): SlamConfig gathers the
/// front-end, dynamic-source, filter and pipeline parameters, and one table of keys
/// (config_keys()) maps `section.field` names to them. The CLI (`ds3d-slam --config FILE`,
/// `--set KEY=VALUE`, `--dump-config`), the Python bindings (`ds3d.SlamConfig`) and
/// docs/configuration.md all read that table.
///
/// @code
/// ds3d::slam::SlamConfig cfg;                        // every default
/// cfg.set("dynamic.source", "htx");                  // same as --dynamic htx
/// cfg.set("htx.min_score", "0.4");                   // same as --set htx.min_score=0.4
/// ds3d::slam::apply_config_file(cfg, "run.yaml");    // YAML or JSON, nested or dotted keys
/// auto source = ds3d::slam::make_dynamic_source(cfg);
/// @endcode

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/slam/dynamic/geometric_motion.hpp"
#include "ds3d/slam/slam_frontend.hpp"

namespace ds3d::slam {

/// How the geometric source gates the boxes of the dynamic source (`--gate`).
enum class Gate : std::uint8_t {
  kNone,      ///< boxes as the source reports them
  kMotion,    ///< only in frames where the geometric source sees motion (MotionGatedSource)
  kEvidence,  ///< boxes whose geometric evidence is significant, tracked
              ///< (MotionGateParams::evidence)
};

/// "none", "motion" or "evidence".
[[nodiscard]] const char* to_string(Gate gate) noexcept;
/// Parses "none", "motion" or "evidence". @throws ds3d::InvalidArgument naming the value.
[[nodiscard]] Gate parse_gate(std::string_view text);

/// Everything a SLAM run is configured by, except the camera (from the dataset or `--camera`).
/// Fields are set directly or by key (set(), config_keys()); validate() checks them all.
struct SlamConfig {
  /// Source: none, geometric, htx, file:PATH, mask:DIR or A+B (key dynamic.source). The default,
  /// geometric, needs no weights and is real time on 2 cores (README, "Which --dynamic to use").
  std::string dynamic = "geometric";
  Gate gate = Gate::kNone;            ///< gate by the geometric source (key dynamic.gate)
  std::filesystem::path weights{};    ///< HTx weights; empty = find_default_weights()
  FrontendConfig frontend{};          ///< tracking, mapping, keyframes (its camera is not a key)
  HtxSourceParams htx{};              ///< the htx source
  GeometricMotionParams geometric{};  ///< the geometric source (also the gate's motion source)
  MotionGateParams gate_params{};     ///< the gate (keys gate.*; evidence follows `gate`)
  DynamicFilterParams filter{};       ///< the box-gated HDBSCAN keypoint filter
  FileSourceParams file{};            ///< the file:PATH source
  PipelineOptions pipeline{};         ///< threading of the pipeline stages
  int cv_threads = 1;                 ///< OpenCV's own worker threads, >= 0 (0 = OpenCV's default)

  /// Sets the field named `key` (config_keys()) from its text form: booleans true/false (also
  /// 1/0, yes/no, on/off), integers and numbers in C syntax, strings as they are.
  /// @throws ds3d::InvalidArgument naming the key and the value when the key is unknown or the
  ///   text does not parse as the field's type (ranges are checked by validate()).
  void set(std::string_view key, std::string_view value);
  /// The text form of the field named `key` (what --dump-config prints).
  /// @throws ds3d::InvalidArgument for an unknown key.
  [[nodiscard]] std::string get(std::string_view key) const;
  /// Checks every section (FrontendConfig::validate() without the camera, HtxSourceParams, ...).
  /// @throws ds3d::InvalidArgument naming the bad field.
  void validate() const;
};

/// One configuration key: its name, type, help line and accessors.
struct ConfigKey {
  std::string name;                                   ///< `section.field`, e.g. "htx.min_score"
  std::string type;                                   ///< bool, int, number or string
  std::string help;                                   ///< one line: meaning, [unit], range
  std::function<std::string(const SlamConfig&)> get;  ///< text form
  std::function<void(SlamConfig&, std::string_view)> set;  ///< parse and store
};

/// Every key, in a fixed order (sections, then fields as declared).
[[nodiscard]] const std::vector<ConfigKey>& config_keys();

/// Applies a YAML or JSON file: a mapping of keys to values, nested by section
/// (`htx: {min_score: 0.4}`) or dotted (`htx.min_score: 0.4`), in any mix.
/// @throws ds3d::IoError when the file cannot be read or parsed (naming it and the line);
///   ds3d::InvalidArgument for an unknown key or a bad value (naming the key and the file).
void apply_config_file(SlamConfig& config, const std::filesystem::path& file);

/// Every key with its value in `config` and its help line, as YAML that apply_config_file reads.
[[nodiscard]] std::string dump_config(const SlamConfig& config = {});

/// The same as a Markdown table (key, default, description), for docs/configuration.md.
[[nodiscard]] std::string config_markdown(const SlamConfig& config = {});

/// The options make_dynamic_source(spec, options) takes, from `config`.
[[nodiscard]] DynamicSourceOptions source_options(const SlamConfig& config);

/// Under the motion gate (`--gate motion`) the htx source carries a missed box at most this many
/// frames and seconds (htx.hold_frames and htx.hold_seconds, when larger, are lowered to these):
/// the geometric source already reports a person for 90 frames after his last motion, and a
/// longer hold only removes people who stopped (docs/dynamic.md).
inline constexpr int kMotionGateHoldFrames = 10;
inline constexpr double kMotionGateHoldSeconds = 0.5;  ///< see kMotionGateHoldFrames

/// The source `config` names: make_dynamic_source(config.dynamic, source_options(config)), then,
/// with a gate, MotionGatedSource over it and a GeometricMotionSource(config.geometric); under
/// the evidence gate the htx source carries no boxes itself (htx.hold_frames 0: the gate's tracks
/// hold them), under the motion gate at most kMotionGateHoldFrames frames and
/// kMotionGateHoldSeconds.
/// @throws ds3d::InvalidArgument for a bad spec, a gate on "none", or bad parameters;
///   ds3d::IoError for unreadable detections or weights files.
[[nodiscard]] std::shared_ptr<DynamicObjectSource> make_dynamic_source(const SlamConfig& config);

/// The box-gated HDBSCAN masker for `config` (config.filter), or nullptr when config.dynamic is
/// "none" (nothing to mask).
[[nodiscard]] std::shared_ptr<DynamicFeatureMasker> make_masker(const SlamConfig& config);

}  // namespace ds3d::slam
