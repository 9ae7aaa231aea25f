// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file orb_features.hpp
/// @brief ORB features spread evenly over an RGB-D image (ds3d::slam, needs OpenCV).
///
/// Detection follows ORB-SLAM2 (Mur-Artal & Tardós 2017, §III): an image pyramid (default 8
/// levels, scale 1.2); per level FAST corners (Rosten & Drummond 2006) bucketed on a grid of
/// cells with a fallback to a lower threshold in cells that found nothing; the number of features
/// per level follows a geometric series so that every level gets features in proportion to its
/// area. Orientation is the intensity centroid (Rosin 1999) and the descriptor is OpenCV's rotated
/// BRIEF (Rublee et al. 2011). Each keypoint is then undistorted and given the depth measured at
/// its pixel, which makes it a "close" (reliable depth) or "far" point as in ORB-SLAM2's RGB-D
/// mode.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/detail/abi_guard.hpp"

namespace ds3d::slam {

/// Parameters of the ORB extractor. Defaults are ORB-SLAM2's for 640×480 RGB-D input.
struct OrbParams {
  int num_features = 1000;    ///< target number of features over all levels, > 0
  int num_levels = 8;         ///< pyramid levels, in [1, 16]
  double scale_factor = 1.2;  ///< scale between consecutive levels, in (1, 2]
  int fast_threshold = 20;    ///< FAST intensity threshold, in [1, 255]
  int min_fast_threshold =
      7;               ///< fallback threshold for cells with no corner, in [1, fast_threshold]
  int cell_size = 35;  ///< grid cell edge [px at that level], >= 8
  double max_depth =
      3.0;  ///< keypoints up to this depth [m] are "close" (ORB-SLAM2's ThDepth), > 0
  double min_depth = 0.1;   ///< depths below this [m] are treated as missing, >= 0
  double max_range = 10.0;  ///< depths beyond this [m] are treated as missing, >= max_depth
  void validate() const;    ///< throws ds3d::InvalidArgument naming the bad field
};

/// The features of one frame. All vectors have one entry per keypoint, in the same order as the
/// rows of `descriptors`.
struct OrbFeatures {
  std::vector<cv::KeyPoint>
      keypoints;        ///< raw (distorted) pixels, level-0 coordinates; octave = level
  cv::Mat descriptors;  ///< N×32 CV_8U rotated-BRIEF descriptors
  std::vector<Eigen::Vector2f> undistorted;  ///< undistorted pixel (u, v) with the same intrinsics
  std::vector<float>
      depth;  ///< depth [m] at the keypoint; 0 when missing or outside [min_depth, max_range]
  float close_depth = 3.0F;  ///< params.max_depth: the close/far threshold [m]
  /// Number of keypoints.
  [[nodiscard]] std::size_t size() const noexcept { return keypoints.size(); }
  /// True if keypoint i has a measured depth.
  [[nodiscard]] bool has_depth(std::size_t i) const noexcept { return depth[i] > 0.0F; }
  /// True if keypoint i is "close" (depth measured and <= close_depth): reliable enough to create
  /// a map point from one frame (ORB-SLAM2, §III-A).
  [[nodiscard]] bool is_close(std::size_t i) const noexcept {
    return depth[i] > 0.0F && depth[i] <= close_depth;
  }
};

/// What OrbExtractor::extract found in one image before it chose its features: the FAST corners of
/// every pyramid level, bucketed and sorted, and the features it picked and described from them.
/// Another extractor with the same pyramid settings (OrbCorners::shares_pyramid) gets its own
/// features from these with OrbExtractor::extract_from, instead of detecting again: SlamFrontend
/// hands them to its dynamic-object source through FrameInput::orb_corners.
struct OrbCorners {
  int width = 0;     ///< level-0 image width [px]
  int height = 0;    ///< level-0 image height [px]
  OrbParams params;  ///< the extractor's parameters
  /// Per pyramid level (as many as were detected), per grid cell: corners in the level's pixels,
  /// best response first.
  std::vector<std::vector<std::vector<cv::KeyPoint>>> cells;
  std::vector<cv::KeyPoint> picked;  ///< the chosen keypoints as handed to the descriptor
  OrbFeatures described;             ///< what the descriptor returned for `picked`
  /// True when an extractor with `p` on a `w`×`h` image builds the same pyramid and corners:
  /// equal num_levels, scale_factor, fast_threshold, min_fast_threshold, cell_size and size.
  [[nodiscard]] bool shares_pyramid(const OrbParams& p, int w, int h) const noexcept;
};

/// Grid-bucketed multi-scale ORB extractor.
/// @note Deterministic (no randomness); `extract` is const and safe to call concurrently.
class OrbExtractor {
 public:
  /// @throws ds3d::InvalidArgument on bad params.
  explicit OrbExtractor(const OrbParams& params = {});

  /// Detects and describes features of a grey (CV_8UC1) or BGR (CV_8UC3) image, and attaches
  /// depth from `depth` (CV_16UC1 in camera.depth_scale units per metre, 0 = missing; may be
  /// empty: then every keypoint is "far").
  /// @param image  the colour or grey image, camera.width × camera.height
  /// @param depth  registered depth image of the same size, or empty
  /// @param camera intrinsics and distortion used to undistort keypoints
  /// @throws ds3d::InvalidArgument on wrong image types or sizes.
  /// @note O(pixels) time; about 1000 features on 640×480 in a few milliseconds.
  [[nodiscard]] OrbFeatures extract(const cv::Mat& image, const cv::Mat& depth,
                                    const PinholeCamera& camera) const;
  /// As above (the returned features are the same), and fills `spare.keypoints` with about
  /// `spare_count` further candidates (shares rounded per level): the ones the even spread
  /// would pick next, per level in the same proportions, with their orientation (no
  /// descriptors: describe() computes them for the ones used). A dynamic filter that removes keypoints can replace them from these
  /// (SlamFrontend, FrontendConfig::spare_features).
  /// @throws ds3d::InvalidArgument as above, or for spare_count < 0.
  [[nodiscard]] OrbFeatures extract(const cv::Mat& image, const cv::Mat& depth,
                                    const PinholeCamera& camera, OrbFeatures& spare,
                                    int spare_count) const;

  /// As extract(image, depth, camera, spare, spare_count), and records the corners and the
  /// described features in `corners` (replacing what it held).
  [[nodiscard]] OrbFeatures extract(const cv::Mat& image, const cv::Mat& depth,
                                    const PinholeCamera& camera, OrbFeatures& spare,
                                    int spare_count, OrbCorners& corners) const;

  /// The features extract(image, depth, camera) returns, bit for bit, taken from the corners
  /// another extractor recorded on the same image: this extractor's even spread over
  /// `corners.cells`, and each chosen keypoint's descriptor from `corners.described`. About 30×
  /// cheaper than extract() (0.17 against 5.3 ms for 800 features of a 640×480 image,
  /// orb_features_bench). Returns nothing (the caller extracts) when the pyramids differ
  /// (OrbCorners::shares_pyramid with camera.width × camera.height) or when a chosen keypoint is
  /// not among the described ones (this extractor wants more features per level than the other).
  /// @param corners what another extractor recorded on this frame's image
  /// @param depth   as for extract()
  /// @param camera  as for extract(); its size must be the image's
  /// @throws ds3d::InvalidArgument as extract() for a bad camera or depth.
  [[nodiscard]] std::optional<OrbFeatures> extract_from(const OrbCorners& corners,
                                                        const cv::Mat& depth,
                                                        const PinholeCamera& camera) const;

  /// Descriptors, undistorted pixels and depth of given keypoints (e.g. spare candidates of
  /// extract()), with the inputs of extract(); unchecked: the caller passes what extract() took.
  [[nodiscard]] OrbFeatures describe(const cv::Mat& image, std::vector<cv::KeyPoint> keypoints,
                                     const cv::Mat& depth, const PinholeCamera& camera) const;

  /// Scale of pyramid level `level` relative to level 0 (scale_factor^level).
  [[nodiscard]] double level_scale(int level) const {
    return scales_.at(static_cast<std::size_t>(level));
  }
  /// The parameters as validated by the constructor.
  [[nodiscard]] const OrbParams& params() const noexcept { return params_; }

 private:
  OrbFeatures extract_impl(const cv::Mat& image, const cv::Mat& depth, const PinholeCamera& camera,
                           OrbFeatures* spare, int spare_count, OrbCorners* corners) const;
  void detect_levels(const cv::Mat& gray, std::vector<cv::KeyPoint>& keypoints,
                     std::vector<cv::KeyPoint>* spare, int spare_count, OrbCorners* corners) const;
  static void check_inputs(const cv::Mat* image, const cv::Mat& depth, const PinholeCamera& camera,
                           const char* fn);
  OrbFeatures describe_gray(const cv::Mat& gray, std::vector<cv::KeyPoint> keypoints,
                            const cv::Mat& depth, const PinholeCamera& camera) const;
  void attach_geometry(OrbFeatures& out, const cv::Mat& depth, const PinholeCamera& camera) const;
  OrbParams params_;
  std::vector<double> scales_;
  std::vector<int> features_per_level_;
};

/// Hamming distance between two 32-byte ORB descriptors (rows of an N×32 CV_8U matrix).
[[nodiscard]] int descriptor_distance(const std::uint8_t* a, const std::uint8_t* b) noexcept;

}  // namespace ds3d::slam
