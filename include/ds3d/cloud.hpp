// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file cloud.hpp
/// @brief Point-cloud traits: how ds3d reads the user's own point types (STYLE.md §2).
///
/// Every algorithm in ds3d takes any type `C` for which `PointCloudTraits<C>` is specialised
/// with two static functions, `size(c)` and `point(c, i)`. ds3d only reads through them, never
/// writes, so an adaptor for an existing SLAM system's keypoint or point type is a few lines:
/// @code
/// struct MyPoint { float x, y, z; std::uint8_t r, g, b; };
/// template <> struct ds3d::PointCloudTraits<std::vector<MyPoint>> {
///   static std::size_t size(const std::vector<MyPoint>& c) { return c.size(); }
///   static Eigen::Vector3f point(const std::vector<MyPoint>& c, std::size_t i) {
///     return {c[i].x, c[i].y, c[i].z};
///   }
/// };
/// static_assert(ds3d::PointCloud<std::vector<MyPoint>>);
/// @endcode
/// Specialisations shipped here: `Points3f` (row-major N×3 float, numpy-compatible), `Points3d`
/// (row-major N×3 double, read as float), `std::vector<Eigen::Vector3f>`,
/// `std::vector<std::array<float, 3>>`, and `Eigen::Ref<const Points3f>`.

#include <array>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace ds3d {

/// N×3 float points, row-major so that a numpy (N, 3) float32 array maps onto it without a copy.
using Points3f = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// N×3 double points, row-major (numpy float64). Read as float by the algorithms.
using Points3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// What an algorithm does with a point that has a NaN or ±inf coordinate.
enum class NonFinite : std::uint8_t {
  kSkip,   ///< ignore it (it is in no output) and count it in the Result
  kThrow,  ///< throw ds3d::InvalidArgument naming the first such row
};

/// Specialise for your cloud type: `static std::size_t size(const C&)` and
/// `static Eigen::Vector3f point(const C&, std::size_t i)` (metres, any frame).
template <class C>
struct PointCloudTraits;

/// A type ds3d can read points from (see PointCloudTraits).
template <class C>
concept PointCloud = requires(const C& c, std::size_t i) {
  { PointCloudTraits<C>::size(c) } -> std::convertible_to<std::size_t>;
  { PointCloudTraits<C>::point(c, i) } -> std::convertible_to<Eigen::Vector3f>;
};

namespace cloud {
/// Number of points in `c` (including non-finite ones).
template <PointCloud C>
[[nodiscard]] inline std::size_t size(const C& c) {
  return static_cast<std::size_t>(PointCloudTraits<C>::size(c));
}
/// Point `i` of `c`, 0 <= i < size(c); no bounds check.
template <PointCloud C>
[[nodiscard]] inline Eigen::Vector3f point(const C& c, std::size_t i) {
  return PointCloudTraits<C>::point(c, i);
}
/// True iff all three coordinates are finite.
[[nodiscard]] inline bool is_finite(const Eigen::Vector3f& p) {
  return std::isfinite(p.x()) && std::isfinite(p.y()) && std::isfinite(p.z());
}
/// Copies any cloud into a Points3f (one row per input point, order kept).
/// @note O(n) time and memory.
template <PointCloud C>
[[nodiscard]] Points3f to_points3f(const C& c) {
  const std::size_t n = size(c);
  Points3f out(static_cast<Eigen::Index>(n), 3);
  for (std::size_t i = 0; i < n; ++i) {
    out.row(static_cast<Eigen::Index>(i)) = point(c, i).transpose();
  }
  return out;
}
}  // namespace cloud

/// Traits of Points3f: one point per row (numpy (N, 3) float32 without a copy).
template <>
struct PointCloudTraits<Points3f> {
  /// Number of rows.
  static std::size_t size(const Points3f& c) { return static_cast<std::size_t>(c.rows()); }
  /// Row i as a column vector [m]; no bounds check.
  static Eigen::Vector3f point(const Points3f& c, std::size_t i) {
    return c.row(static_cast<Eigen::Index>(i)).transpose();
  }
};

/// Traits of Points3d: one point per row, read as float (numpy (N, 3) float64).
template <>
struct PointCloudTraits<Points3d> {
  /// Number of rows.
  static std::size_t size(const Points3d& c) { return static_cast<std::size_t>(c.rows()); }
  /// Row i rounded to float [m]; no bounds check.
  static Eigen::Vector3f point(const Points3d& c, std::size_t i) {
    return c.row(static_cast<Eigen::Index>(i)).transpose().cast<float>();
  }
};

/// Traits of a read-only view of Points3f (what the Eigen overloads and bindings pass on).
template <>
struct PointCloudTraits<Eigen::Ref<const Points3f>> {
  /// Number of rows.
  static std::size_t size(const Eigen::Ref<const Points3f>& c) {
    return static_cast<std::size_t>(c.rows());
  }
  /// Row i as a column vector [m]; no bounds check.
  static Eigen::Vector3f point(const Eigen::Ref<const Points3f>& c, std::size_t i) {
    return c.row(static_cast<Eigen::Index>(i)).transpose();
  }
};

/// Traits of a read-only view of Points3d, read as float.
template <>
struct PointCloudTraits<Eigen::Ref<const Points3d>> {
  /// Number of rows.
  static std::size_t size(const Eigen::Ref<const Points3d>& c) {
    return static_cast<std::size_t>(c.rows());
  }
  /// Row i rounded to float [m]; no bounds check.
  static Eigen::Vector3f point(const Eigen::Ref<const Points3d>& c, std::size_t i) {
    return c.row(static_cast<Eigen::Index>(i)).transpose().cast<float>();
  }
};

/// Traits of std::vector<Eigen::Vector3f> (any allocator).
template <class Alloc>
struct PointCloudTraits<std::vector<Eigen::Vector3f, Alloc>> {
  /// Number of elements.
  static std::size_t size(const std::vector<Eigen::Vector3f, Alloc>& c) { return c.size(); }
  /// Element i [m]; no bounds check.
  static Eigen::Vector3f point(const std::vector<Eigen::Vector3f, Alloc>& c, std::size_t i) {
    return c[i];
  }
};

/// Traits of std::vector<std::array<float, 3>> (any allocator): {x, y, z} per element.
template <class Alloc>
struct PointCloudTraits<std::vector<std::array<float, 3>, Alloc>> {
  /// Number of elements.
  static std::size_t size(const std::vector<std::array<float, 3>, Alloc>& c) { return c.size(); }
  /// Element i as (x, y, z) [m]; no bounds check.
  static Eigen::Vector3f point(const std::vector<std::array<float, 3>, Alloc>& c, std::size_t i) {
    return {c[i][0], c[i][1], c[i][2]};
  }
};

static_assert(PointCloud<Points3f>);
static_assert(PointCloud<Points3d>);
static_assert(PointCloud<std::vector<Eigen::Vector3f>>);
static_assert(PointCloud<std::vector<std::array<float, 3>>>);

}  // namespace ds3d
