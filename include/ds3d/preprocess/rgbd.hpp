// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file rgbd.hpp
/// @brief Depth image → camera-frame points and the (u, v) pixel of each point (TUM convention).
///
/// For a depth value d at column u and row v: `z = d / depth_scale` (16-bit images) or `z = d`
/// (float images in metres), `x = (u - cx) z / fx`, `y = (v - cy) z / fy`, in double, stored as
/// float. With distortion (PinholeCamera k1..k3, p1, p2) the pixel is first undistorted through a
/// per-pixel ray table (PixelRays), which callers processing many frames build once. Depth 0 and
/// NaN are skipped and counted. Output order is row-major (v outer, u inner). No OpenCV: the image
/// is a raw pointer with a row stride, or an Eigen row-major matrix.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "ds3d/camera.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// Row-major 16-bit depth image (numpy uint16 (H, W)).
using DepthImageU16 = Eigen::Matrix<std::uint16_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
/// Row-major float depth image in metres (numpy float32 (H, W)).
using DepthImageF = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
/// (u, v) pixel of each point, row-major N×2 (numpy int32 (N, 2)).
using Pixels2i = Eigen::Matrix<std::int32_t, Eigen::Dynamic, 2, Eigen::RowMajor>;

/// Precomputed normalised rays (x/z, y/z) of every pixel of a camera, undistorted.
/// Build once per camera with make_pixel_rays() and pass it in DepthToPointsParams::rays.
struct PixelRays {
  int width = 0;   ///< image width [px]
  int height = 0;  ///< image height [px]
  /// @name Rays
  /// @{
  std::vector<double> x, y;  ///< ray of pixel (u, v) at index v * width + u
  /// @}
};

/// Undistorted rays of every pixel of `camera` (PinholeCamera::undistort, 20 fixed-point steps).
/// @throws ds3d::InvalidArgument if the camera is invalid.
/// @note O(width · height) time and memory; call once per camera, not per frame.
[[nodiscard]] PixelRays make_pixel_rays(const PinholeCamera& camera);

/// make_pixel_rays() for the last camera seen, for code that back-projects frame after frame
/// (preprocess_bench BM_DepthToPointsDistorted, 640×480, stride 1: ≈ 104 ms per call when the
/// table is built each time, ≈ 14 ms with it cached). Not thread-safe: one cache per thread or
/// per source.
class PixelRayCache {
 public:
  /// Rays for `camera` to pass in DepthToPointsParams::rays: rebuilt only when its size,
  /// intrinsics or distortion differ from the previous call's (depth_scale is ignored);
  /// nullptr for a camera without distortion (depth_to_points needs no table then). The
  /// pointer stays valid until the next call with another camera.
  /// @throws ds3d::InvalidArgument if a camera with distortion is invalid (the cache is left
  ///   unchanged); a camera without distortion is not checked here (depth_to_points does).
  [[nodiscard]] const PixelRays* get(const PinholeCamera& camera);

 private:
  PinholeCamera camera_{};
  PixelRays rays_{};
  bool valid_ = false;
};

/// Region of interest in pixels; width or height 0 means "to the image border".
struct PixelRoi {
  int u0 = 0;      ///< first column, >= 0
  int v0 = 0;      ///< first row, >= 0
  int width = 0;   ///< columns, >= 0 (0: up to the right border)
  int height = 0;  ///< rows, >= 0 (0: up to the bottom border)
};

/// Parameters of depth_to_points().
struct DepthToPointsParams {
  int stride = 1;          ///< take every stride-th pixel in u and v (from the ROI origin), >= 1
  PixelRoi roi{};          ///< pixels considered; must lie inside the image
  double min_depth = 0.0;  ///< points with z < min_depth [m] are skipped and counted, >= 0
  double max_depth = std::numeric_limits<double>::infinity();  ///< z > max_depth skipped, > min
  bool undistort = true;            ///< apply the camera's distortion model if it has one
  const PixelRays* rays = nullptr;  ///< optional precomputed rays (must match the camera size)
  /// Throws ds3d::InvalidArgument naming the bad field and value.
  void validate() const;
};

/// Output of depth_to_points().
struct DepthToPointsResult {
  Points3f points;                   ///< camera-frame points [m], row-major pixel order
  Pixels2i pixels;                   ///< (u, v) of each point
  std::size_t num_invalid = 0;       ///< visited pixels with depth 0 or NaN (or negative/inf float)
  std::size_t num_out_of_range = 0;  ///< valid pixels outside [min_depth, max_depth]
};

/// Back-projects a 16-bit depth image.
/// @param depth       pointer to the first pixel of row 0; rows are `row_stride` elements apart
/// @param width,height image size [px]; must equal camera.width and camera.height
/// @param row_stride  elements between rows, >= width
/// @param camera      intrinsics and depth_scale (units per metre, TUM: 5000)
/// @param params      stride, ROI, depth range, undistortion
/// @throws ds3d::InvalidArgument on a null pointer, a size mismatch, bad camera or params.
/// @note O(pixels visited); deterministic.
[[nodiscard]] DepthToPointsResult depth_to_points(const std::uint16_t* depth, int width, int height,
                                                  std::ptrdiff_t row_stride,
                                                  const PinholeCamera& camera,
                                                  const DepthToPointsParams& params = {});

/// Back-projects a float depth image in metres (NaN, inf, 0 and negative values are invalid).
/// Parameters as the 16-bit overload; camera.depth_scale is not used.
[[nodiscard]] DepthToPointsResult depth_to_points(const float* depth, int width, int height,
                                                  std::ptrdiff_t row_stride,
                                                  const PinholeCamera& camera,
                                                  const DepthToPointsParams& params = {});

/// Eigen overload (numpy uint16 (H, W) maps without a copy when C-contiguous).
[[nodiscard]] DepthToPointsResult depth_to_points(
    const Eigen::Ref<const DepthImageU16, 0, Eigen::OuterStride<>>& depth,
    const PinholeCamera& camera, const DepthToPointsParams& params = {});

/// Eigen overload for float depth in metres.
[[nodiscard]] DepthToPointsResult depth_to_points(
    const Eigen::Ref<const DepthImageF, 0, Eigen::OuterStride<>>& depth,
    const PinholeCamera& camera, const DepthToPointsParams& params = {});

}  // namespace ds3d

#include "ds3d/detail/rgbd_impl.hpp"
