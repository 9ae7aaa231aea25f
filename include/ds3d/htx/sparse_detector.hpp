// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file sparse_detector.hpp
/// @brief HTx-lite 3-D detector: 3DETR encoder/decoder (Misra et al., "An End-to-End
/// Transformer Model for 3D Object Detection", ICCV 2021) with a Part-A2 part head (Shi et al.,
/// TPAMI 2020), inference in Eigen only (htx spec §3 and §6).
///
/// Pipeline of one frame: farthest point sampling (FPS) of `num_centres` tokens from index 0;
/// ball query "first `sa_samples` by index" of radius `sa_radius`; shared MLP 3->32->64->128 with
/// max-pool; `enc_layers` pre-norm transformer layers; a 2-layer projection; `num_queries`
/// queries by FPS over the tokens with a Fourier positional embedding; `dec_layers` pre-norm
/// decoder layers; five MLP heads; box decoding; post-processing (drop boxes holding fewer than
/// `min_points_in_box` input points, objectness > `score_threshold`, same-class axis-aligned
/// 3-D NMS at IoU `nms_iou`). The PyTorch reference is ds3d.htx (python/ds3d/htx); with the same
/// weights file the outputs agree within 1e-4 and the sampling indices are identical.
///
/// **Expected input**: one preprocessed view, gravity-aligned (Z up, metres; the SUN RGB-D
/// upright depth frame of box3.hpp), typically 4,096 points drawn after voxel downsampling,
/// ground-plane and outlier removal (htx spec §6.1). The scene box used for normalisation is
/// the per-axis min/max of exactly these points. Points with |p|^2 <= 1e-3 are treated as
/// padding by FPS (3DETR rule), so do not centre the cloud on a real point.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ds3d/box3.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/detail/abi_guard.hpp"

namespace ds3d {

class WeightsFile;

/// Architecture and post-processing numbers, read from the weights file's metadata (`config`,
/// written by ds3d.htx.export); mirrors ds3d/htx/config.py.
struct DetectorConfig {
  std::string profile;      ///< "fast" or "quality" (informational)
  int num_centres = 384;    ///< FPS tokens of the set-abstraction layer
  float sa_radius = 0.25F;  ///< ball-query radius [m]
  int sa_samples = 32;      ///< samples per ball
  std::vector<int> sa_mlp;  ///< shared-MLP widths, last = d_model
  int d_model = 128;        ///< transformer width
  int num_heads = 4;        ///< attention heads (d_model divisible by it)
  int enc_layers = 2;       ///< encoder layers
  int enc_ffn = 128;        ///< encoder FFN width
  int dec_layers = 3;       ///< decoder layers
  int dec_ffn = 128;        ///< decoder FFN width
  int num_queries = 64;     ///< box queries
  int num_classes = 1;      ///< K (the class head has K + 1 outputs, last = background)
  std::vector<std::string> class_names;  ///< K names
  int num_angle_bins = 12;               ///< heading bins
  int head_hidden = 128;                 ///< hidden width of the box heads
  int part_hidden = 64;                  ///< hidden width of the part head
  float layer_norm_eps = 1e-5F;          ///< LayerNorm epsilon
  int min_points_in_box = 5;             ///< boxes holding fewer input points are dropped
  float nms_iou = 0.25F;            ///< NMS suppresses same-class boxes with AABB IoU above this
  float score_threshold = 0.05F;    ///< boxes need objectness above this
  float min_size_extent = 0.1F;     ///< size = sigmoid * max(scene extent, this) [m]
  float fps_padding_norm2 = 1e-3F;  ///< FPS never picks points with |p|^2 <= this

  /// Parses the JSON object written by the exporter. @throws ds3d::IoError naming the key.
  [[nodiscard]] static DetectorConfig from_json(std::string_view json);
  /// Throws ds3d::IoError naming the first inconsistent value.
  void validate() const;
  /// The JSON object from_json() reads (what ds3d.htx.export writes as metadata `config`).
  [[nodiscard]] std::string to_json() const;
  /// Built-in profile "fast" (384 tokens) or "quality" (512 tokens), htx spec §6.2 (person-only,
  /// K = 1). @throws ds3d::InvalidArgument for another name.
  [[nodiscard]] static DetectorConfig make_profile(std::string_view name);
};

/// Options of SparseDetector::run().
struct DetectOptions {
  int num_threads = 1;       ///< attention is split over heads on this many threads; 0 = all
  bool part_logits = false;  ///< also run the part head on every input point
};

/// Everything one forward pass produces (for parity checks, the SLAM masking and debugging).
struct DetectorOutput {
  std::vector<Box3> boxes;                   ///< final detections, decreasing objectness
  std::vector<std::int32_t> centre_indices;  ///< [tokens] FPS indices into the input
  std::vector<std::int32_t> query_indices;   ///< [queries] FPS indices into the tokens
  std::vector<Box3> proposals;               ///< [queries] decoded boxes before post-processing
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> class_prob;  ///< [q, K]
  /// [n, 4] per input point: foreground logit, then 3 part-location logits (sigmoid gives the
  /// Part-A2 location in [0,1]^3); empty unless DetectOptions::part_logits.
  Eigen::Matrix<float, Eigen::Dynamic, 4, Eigen::RowMajor> part_logits;
};

/// Options of make_detector_input() (htx spec §6.1 step 5).
struct DetectorInputParams {
  int num_points = 4096;   ///< points given to the detector, >= 1
  std::uint64_t seed = 0;  ///< seed of the draw: the same seed and cloud give the same points
  void validate() const;   ///< throws ds3d::InvalidArgument naming the bad field
};

/// One detector input: a gravity-aligned cloud drawn from a camera-frame cloud.
struct DetectorInput {
  Points3f points;                  ///< [num_points, 3] upright frame (X right, Y fwd, Z up) [m]
  std::vector<std::uint32_t> rows;  ///< for each point, its row in the camera-frame cloud
  Eigen::Matrix3f R_up_cam = Eigen::Matrix3f::Identity();  ///< p_up = R_up_cam * p_cam
};

/// Rotation from the camera frame (x right, y down, z forward) to the upright depth frame of
/// box3.hpp (X right, Y forward, Z up) that maps `up_cam` (the floor normal seen by the camera,
/// e.g. PreprocessResult::ground_plane.head<3>()) to +Z: the axis swap (x, y, z) → (x, z, −y),
/// then Z = the normal, Y = the optical axis projected onto the floor, X = Y × Z (the role of
/// SUN RGB-D's tilt matrix, htx spec §6.1 step 3; the convention the trainer uses,
/// `ds3d.htx.data.gravity_rotation`). A camera-frame −y gives the plain axis swap.
/// @param up_cam up direction in the camera frame, finite and non-zero (any length)
/// @throws ds3d::InvalidArgument for a zero or non-finite vector, or one pointing down
///   (more than 90° from camera −y: a floor is never above the camera's horizon).
/// @note O(1); the camera's heading (rotation about the vertical) is kept.
[[nodiscard]] Eigen::Matrix3f upright_rotation(const Eigen::Vector3d& up_cam);

/// Builds the detector input from a preprocessed camera-frame cloud (preprocess.hpp): rotates
/// it with `R_up_cam` and draws `num_points` rows with a seeded generator. With more rows than
/// num_points they are drawn without replacement; with fewer, every row is taken once and the
/// rest drawn with replacement (3DETR draws with replacement then; keeping every point loses
/// nothing). The drawn rows are in random order (FPS starts at row 0, the ball query takes the
/// first rows by index, so a spatially sorted order would bias both).
/// @param cloud_cam [n, 3] camera-frame points [m], finite; n = 0 gives an empty input
/// @param R_up_cam camera → upright rotation (upright_rotation()); p_up = R_up_cam · p_cam
/// @param params number of points to draw (> 0) and the seed
/// @throws ds3d::InvalidArgument for bad params or a non-finite point (naming its row).
/// @note O(n + num_points); deterministic for a given seed on every platform (own generator).
[[nodiscard]] DetectorInput make_detector_input(Eigen::Ref<const Points3f> cloud_cam,
                                                const Eigen::Matrix3f& R_up_cam,
                                                const DetectorInputParams& params = {});

/// The HTx-lite detector. Immutable after load(); `detect()` and `run()` are const and safe to
/// call concurrently from several threads (no shared scratch state).
class SparseDetector {
 public:
  /// Loads a weights file written by ds3d.htx.export (format "ds3d-htx", version 1).
  /// @throws ds3d::IoError for any defect of the file, naming the tensor and both shapes.
  [[nodiscard]] static SparseDetector load(const std::filesystem::path& weights);
  /// Builds the detector from an already validated file. @throws ds3d::IoError.
  [[nodiscard]] static SparseDetector from_weights(const WeightsFile& weights);

  /// Detects boxes in one preprocessed, gravity-aligned cloud (see the file comment).
  /// @param xyz [n, 3] points [m], finite; n = 0 gives no boxes
  /// @param num_threads threads for attention (0 = all hardware threads)
  /// @return boxes in decreasing objectness; Box3::score = p[label] * objectness
  /// @throws ds3d::InvalidArgument for a non-finite point (naming its row) or num_threads < 0
  /// @note Deterministic: the same input gives the same output for any num_threads. Cost is
  ///       O(n * num_centres) for sampling plus the network (~0.85 GFLOP for the fast profile).
  [[nodiscard]] std::vector<Box3> detect(Eigen::Ref<const Points3f> xyz, int num_threads = 1) const;

  /// Like detect() but returns every intermediate listed in DetectorOutput.
  [[nodiscard]] DetectorOutput run(Eigen::Ref<const Points3f> xyz,
                                   const DetectOptions& options = {}) const;

  /// Post-processing alone (spec §3.8) on given proposals: drops boxes with fewer than
  /// min_points_in_box points of `xyz` (keeping the highest-objectness one if all go), keeps
  /// objectness > score_threshold, then same-class AABB NMS. Returns indices into `proposals`.
  /// @note O(q n + q^2); computed in double; deterministic (ties broken by lower index).
  [[nodiscard]] std::vector<std::size_t> postprocess(Eigen::Ref<const Points3f> xyz,
                                                     const std::vector<Box3>& proposals) const;

  /// Every tensor name and shape a weights file for `config` must hold (no more, no fewer).
  [[nodiscard]] static std::vector<std::pair<std::string, std::vector<std::int64_t>>>
  expected_tensors(const DetectorConfig& config);

  /// The configuration read from the weights file.
  [[nodiscard]] const DetectorConfig& config() const noexcept { return config_; }

  struct Weights;  ///< internal, defined in src/htx/sparse_detector_impl.hpp

 private:
  SparseDetector(DetectorConfig config, std::shared_ptr<const Weights> w)
      : config_(std::move(config)), w_(std::move(w)) {}
  DetectorConfig config_;
  std::shared_ptr<const Weights> w_;
};

}  // namespace ds3d
