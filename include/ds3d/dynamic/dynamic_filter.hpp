// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file dynamic_filter.hpp
/// @brief Box-gated HDBSCAN removal of keypoints on moving objects (3DS-SLAM, Shen et al.,
/// §III-C), on plain keypoint arrays (u, v, depth): header-only, no OpenCV.
///
/// Method, per box of a moving object (a 2-D image box, or a 3-D box projected into the image):
///  1. gate: collect the keypoints inside the box; split them into those with a valid depth and
///     those without;
///  2. cluster the valid ones with ds3d::hdbscan on (u, v, z) with per-dimension scales
///     {z̃/fx, z̃/fy, 1} (z̃ = median depth in the box): pixels become metres at the object's depth,
///     so the clustering is isotropic in metric space whatever the distance or the resolution;
///  3. clusters are ordered by nearest depth and chained into depth-continuous groups (a
///     cluster's depth range touches the group's: its near end within the depth gap plus 3σ of
///     the sensor noise σ(z) = k·z², Khoshelham & Elberink 2012, of the group's far end, and its
///     median within max_object_depth of the group's near end): arms, legs and torso that
///     HDBSCAN split into several depth groups join their body. The foreground is the shallowest
///     group spanning a sizeable part of the box height (a detected object fills its box; furniture
///     occluding part of it does not); its clusters are dynamic; everything else in the box (the
///     background seen around and through the object, occluders in front of it) is kept;
///  4. noise points (label −1) are dynamic when their depth lies in the foreground's depth range
///     and they lie in its image rectangle (or anywhere in the box when the box has its own
///     depth range); keypoints without depth are dynamic when they lie in that rectangle (they
///     cannot be verified static);
///  5. boxes with too few keypoints, or where HDBSCAN finds no cluster, fall back to a
///     depth-gap split: sorted depths, the foreground ends at the first gap wider than the depth
///     gap (+3σ);
///  6. the dynamic regions of frame t−1 (image rectangle and depth range) are carried to frame t
///     for `carry_frames` frames when no box of frame t overlaps them, to cover detection misses.
///
/// Two metric gates narrow step 1 when the caller knows more than an image rectangle:
///  * a **solid** (ImageBox::solid, an oriented 3-D box in the camera frame with its own metric
///    uncertainty): a keypoint with depth is back-projected (undistorted) and gated in only when it
///    lies inside the box grown by that uncertainty plus 3σ of its depth noise along each box axis
///    (the rectangle and depth range of a projected box also hold the floor around a person's feet
///    and whatever stands beside it at the same depth);
///  * a **support plane** (the floor, camera frame): keypoints within `support_margin` plus 3σ of
///    their depth noise (propagated onto the plane normal) of it are static, in every box: floor
///    texture around a person's feet is not the person.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ds3d/camera.hpp"
#include "ds3d/cluster/hdbscan.hpp"
#include "ds3d/detail/core_separate.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// Keypoints as rows (u, v, z): pixel column and row [px, raw image], depth [m]. A depth that is
/// not finite or <= 0 means "no depth". Row-major, numpy-compatible.
using Keypoints3f = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// An oriented 3-D box in the camera frame (x right, y down, z forward) with a metric uncertainty:
/// the volume a keypoint must lie in to belong to the object.
struct SolidBox {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();    ///< box centre [m]
  Eigen::Matrix3f axes = Eigen::Matrix3f::Identity();  ///< rows: unit box axes (orthonormal)
  Eigen::Vector3f half = Eigen::Vector3f::Zero();      ///< half sizes along the axes [m], >= 0
  float margin = 0.0F;  ///< the box's own uncertainty [m]: it grows by this per side, >= 0

  /// True if camera-frame point `p` lies in the box grown by `margin` + `grow(axis)` per side.
  /// @param p point [m], camera frame
  /// @param ray ∂p/∂z = (x/z, y/z, 1): the direction a depth error moves the point along
  /// @param sigma_z depth noise σ(z) of the point [m], >= 0; 3σ projected on each axis is added
  /// @note O(1).
  [[nodiscard]] bool contains(const Eigen::Vector3f& p, const Eigen::Vector3f& ray,
                              float sigma_z) const noexcept {
    const Eigen::Vector3f l = axes * (p - centre);
    const Eigen::Vector3f spread = (axes * ray).cwiseAbs() * (3.0F * sigma_z);
    return (l.cwiseAbs().array() <= half.array() + margin + spread.array()).all();
  }
};

/// The oriented box spanned by 8 corners in any order (a cuboid: one corner's three edges are
/// orthogonal and the other corners are their sums), or std::nullopt when the corners do not
/// form a cuboid within `tol` (relative to the largest edge) or are not finite.
/// @param corners 8 × 3 corners [m]
/// @param margin the box's own uncertainty [m], >= 0 (stored in SolidBox::margin)
/// @param tol relative tolerance of the cuboid test, > 0
/// @note O(1): tries the 35 triples of edge candidates from corner 0.
[[nodiscard]] inline std::optional<SolidBox> solid_from_corners(
    const Eigen::Matrix<float, 8, 3>& corners, float margin, float tol = 1e-3F);

/// An axis-aligned image box of a (possibly) moving object, with an optional depth range and an
/// optional oriented 3-D box.
struct ImageBox {
  float x_min = 0.0F;       ///< left edge [px], pixel-centre convention (camera.hpp)
  float y_min = 0.0F;       ///< top edge [px]
  float x_max = 0.0F;       ///< right edge [px], >= x_min
  float y_max = 0.0F;       ///< bottom edge [px], >= y_min
  float score = 1.0F;       ///< detection confidence in [0, 1]
  std::int32_t label = -1;  ///< class id (informative; -1 = unknown)
  float z_min = 0.0F;       ///< nearest depth of the object [m] when known (3-D box), else 0
  float z_max = 0.0F;       ///< farthest depth [m] when known, else 0 (z_max > 0 = known)
  /// The object's oriented 3-D box, when known with a finite uncertainty: keypoints with depth
  /// are then gated in 3-D (inside the grown box), not by the rectangle and depth range alone.
  std::optional<SolidBox> solid{};

  /// True when the box carries a depth range (it came from a 3-D box or a carried region).
  [[nodiscard]] bool has_depth_range() const noexcept { return z_max > 0.0F; }
  /// True if pixel (u, v) lies in the box (edges inclusive).
  [[nodiscard]] bool contains(float u, float v) const noexcept {
    return u >= x_min && u <= x_max && v >= y_min && v <= y_max;
  }
  /// Width x_max − x_min [px].
  [[nodiscard]] float width() const noexcept { return x_max - x_min; }
  /// Height y_max − y_min [px].
  [[nodiscard]] float height() const noexcept { return y_max - y_min; }
  /// Intersection over union with another box (0 when either is empty).
  [[nodiscard]] float iou(const ImageBox& o) const noexcept {
    const float iw = std::min(x_max, o.x_max) - std::max(x_min, o.x_min);
    const float ih = std::min(y_max, o.y_max) - std::max(y_min, o.y_min);
    if (iw <= 0.0F || ih <= 0.0F) return 0.0F;
    const float inter = iw * ih;
    const float uni = width() * height() + o.width() * o.height() - inter;
    return uni > 0.0F ? inter / uni : 0.0F;
  }
};

/// Projects the 8 corners of a 3-D box given in the camera frame (x right, y down, z forward,
/// metres; any corner order) to its image box, clipped to the image, with the box's depth range.
/// Parts of the box behind the plane z = min_z are cut off (the hull of the clipped box is used).
/// @param corners_cam 8 × 3 corners [m], camera frame, finite
/// @param camera intrinsics (distortion applied to the projected corners)
/// @param min_z near plane [m], > 0
/// @return std::nullopt when the box is entirely behind the near plane or outside the image.
/// @throws ds3d::InvalidArgument for a non-finite corner or min_z <= 0.
/// @note O(1).
[[nodiscard]] inline std::optional<ImageBox> project_box(
    const Eigen::Matrix<float, 8, 3>& corners_cam, const PinholeCamera& camera,
    double min_z = 0.05);

/// Parameters of DynamicFeatureFilter. Lengths are metric, so the same values hold for any image
/// size, focal length and distance (the pixel → metre scale is computed per box).
struct DynamicFilterParams {
  float min_score = 0.3F;    ///< boxes with a lower score are ignored, in [0, 1]
  float box_margin = 0.05F;  ///< each box grows by this fraction of its size per side, in [0, 1]
  int min_cluster_size = 8;  ///< HDBSCAN min_cluster_size, >= 2
  int min_samples = 4;       ///< HDBSCAN min_samples (core distance k), >= 1
  int min_keypoints = 16;    ///< fewer depth keypoints in a box: depth-gap fallback, >= 2
  float depth_gap = 0.3F;    ///< largest depth gap [m] within one object, > 0
  float max_object_depth = 1.0F;    ///< largest front-to-back extent of one object [m], > 0
  float depth_noise = 1.5e-3F;      ///< sensor noise σ(z) = depth_noise·z² [1/m], >= 0
  float min_vertical_span = 0.35F;  ///< a foreground cluster spans at least this fraction of the
                                    ///< box height, in [0, 1]
  int carry_frames = 1;             ///< frames a dynamic region survives without a box, >= 0
  float carry_iou = 0.3F;     ///< a region overlapping a new box this much is not carried, (0, 1]
  float carry_motion = 0.3F;  ///< carried regions grow by this [m] (object motion per frame), >= 0
  /// Keypoints within this distance [m] of the support plane (plus 3σ of their depth noise along
  /// its normal) are static. Default: preprocess's ground RANSAC inlier threshold (0.02 m), the
  /// band the plane was fitted to. >= 0.
  float support_margin = 0.02F;
  /// Throws ds3d::InvalidArgument naming the first bad field and its value.
  void validate() const;
};

/// What the filter did with one box.
struct BoxOutcome {
  ImageBox box;            ///< the box as used (grown, clipped; carried regions included)
  bool carried = false;    ///< a region carried from a previous frame, not a detection
  bool fallback = false;   ///< decided by the depth-gap fallback instead of HDBSCAN
  int num_keypoints = 0;   ///< keypoints inside the box
  int num_with_depth = 0;  ///< of which with a valid depth
  int num_clusters = 0;    ///< HDBSCAN clusters found (0 for the fallback)
  int num_dynamic = 0;     ///< keypoints of this box marked dynamic
  float z_front = 0.0F;    ///< foreground depth range [m] (0, 0 when none was found)
  float z_back = 0.0F;     ///< far end of the foreground depth range [m]
};

/// Output of DynamicFeatureFilter::filter().
struct DynamicFilterResult {
  std::vector<std::uint8_t> dynamic;  ///< one per keypoint: 1 = on a moving object, 0 = keep
  /// One per keypoint: 1 = a keypoint with depth that passed some box's gates (rectangle, depth
  /// range, support plane, solid) and so went into that box's clustering, dynamic or not.
  std::vector<std::uint8_t> gated;
  int num_on_support = 0;             ///< keypoints in some box kept static on the support plane
  int num_outside_solid = 0;          ///< keypoints in some box's rectangle outside its solid
  std::vector<BoxOutcome> boxes;      ///< one per processed box (detections, then carried regions)
  int num_dynamic = 0;                ///< number of ones in `dynamic`
  std::size_t num_non_finite = 0;     ///< keypoints with a non-finite u or v (always kept)
  std::size_t num_ignored_boxes = 0;  ///< boxes below min_score or outside the image
};

/// Box-gated HDBSCAN dynamic-keypoint filter (3DS-SLAM §III-C). Stateful only through the regions
/// carried from frame to frame (reset() forgets them).
/// @note Deterministic: the same inputs in the same order give the same output. Not thread-safe
///       (filter() updates the carried regions); use one instance per sequence.
class DynamicFeatureFilter {
 public:
  /// @throws ds3d::InvalidArgument on bad params.
  explicit DynamicFeatureFilter(const DynamicFilterParams& params = {}) : params_(params) {
    params_.validate();
  }

  /// Marks the keypoints of one frame that lie on moving objects.
  /// @param keypoints N × 3 rows (u, v, z); z not finite or <= 0 = no depth
  /// @param boxes boxes of moving objects in this frame (finite, x_max >= x_min, y_max >= y_min,
  ///   score in [0, 1]; z range with 0 <= z_min <= z_max when given)
  /// @param camera image size (boxes are clipped to it) and focal lengths (pixel → metre scale)
  /// @param support_plane the supporting plane (floor) in the camera frame, (n, d) with
  ///   n·p + d = 0 (n is normalised here), or std::nullopt; keypoints on it are static
  /// @throws ds3d::InvalidArgument for a malformed box (names its index), a non-finite or
  ///   zero-normal support plane, or a bad camera.
  /// @note O(Σ_box n_b² ) for HDBSCAN's exact MST on the n_b keypoints of each box (Prim below
  ///   3000 points) plus O(N · boxes) for the gating; about 1 ms for 1000 keypoints in a box.
  DynamicFilterResult filter(Eigen::Ref<const Keypoints3f> keypoints,
                             const std::vector<ImageBox>& boxes, const PinholeCamera& camera,
                             const std::optional<Eigen::Vector4f>& support_plane = std::nullopt);

  /// Forgets the carried regions (call between sequences).
  void reset() noexcept { carried_.clear(); }
  /// Regions that the next filter() call will carry when no box overlaps them.
  [[nodiscard]] std::vector<ImageBox> carried_regions() const {
    std::vector<ImageBox> out;
    for (const Carried& c : carried_) out.push_back(c.region);
    return out;
  }
  /// The parameters as validated by the constructor.
  [[nodiscard]] const DynamicFilterParams& params() const noexcept { return params_; }

 private:
  struct Carried {
    ImageBox region;
    int age = 0;  // frames since the region was last backed by a detection
  };
  // Boxes of one frame to process: detections (grown by box_margin, clipped to the image), then
  // the carried regions that no detection overlaps (grown by carry_motion), with their age (-1 =
  // detection). Counts the detections ignored (low score, outside the image) in `num_ignored`.
  [[nodiscard]] std::vector<std::pair<ImageBox, int>> work_boxes(const std::vector<ImageBox>& boxes,
                                                                 const PinholeCamera& camera,
                                                                 std::size_t& num_ignored) const;
  DynamicFilterParams params_;
  std::vector<Carried> carried_;
};

/// Stateless convenience: one frame through a fresh DynamicFeatureFilter (no carrying).
/// @throws ds3d::InvalidArgument like DynamicFeatureFilter::filter.
[[nodiscard]] inline DynamicFilterResult filter_dynamic_keypoints(
    Eigen::Ref<const Keypoints3f> keypoints, const std::vector<ImageBox>& boxes,
    const PinholeCamera& camera, const DynamicFilterParams& params = {},
    const std::optional<Eigen::Vector4f>& support_plane = std::nullopt) {
  DynamicFilterParams p = params;
  p.carry_frames = 0;
  DynamicFeatureFilter f(p);
  return f.filter(keypoints, boxes, camera, support_plane);
}

}  // namespace ds3d

#if !defined(DS3D_CORE_SEPARATE) || defined(DS3D_CORE_IMPLEMENTATION)
#include "ds3d/detail/dynamic_filter_impl.hpp"
#endif
