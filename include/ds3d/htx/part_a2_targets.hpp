// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file part_a2_targets.hpp
/// @brief Part-A2 intra-object part-location targets (Shi et al., "From Points to Parts",
/// TPAMI 2020; OpenPCDet point_head_template.py assign_stack_targets), seed eq. 2 of 3DS-SLAM
/// with Part-A2's "+0.5" (htx spec §5).
///
/// For each point: foreground if inside a box (the first box containing it, in box order);
/// "ignore" if inside some box grown by `extra_width` metres per full size but inside none of
/// the boxes; background otherwise. A foreground point's target is its box-frame coordinate
/// divided by the full sizes plus 0.5, in [0, 1]^3 (0.5 = centre), using the box convention of
/// box3.hpp (rotation by +yaw). The Python twin is ds3d.htx.part_targets (agreement 1e-6).

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "ds3d/box3.hpp"
#include "ds3d/cloud.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

/// Parameters of part_a2_targets().
struct PartTargetParams {
  double extra_width = 0.2;                    ///< growth of every full size for "ignore" [m], >= 0
  NonFinite on_non_finite = NonFinite::kSkip;  ///< kSkip: label 0 and counted; kThrow: throw
  /// Throws ds3d::InvalidArgument naming the bad value.
  void validate() const {
    DS3D_CHECK(std::isfinite(extra_width) && extra_width >= 0.0,
               "ds3d::part_a2_targets: extra_width must be finite and >= 0 (got ", extra_width,
               ")");
  }
};

/// Per-point labels and part targets (one entry per input point, input order).
struct PartTargets {
  std::vector<std::int8_t> label;       ///< 1 foreground, 0 background, -1 ignore
  std::vector<std::int32_t> box_index;  ///< index into boxes of the foreground box, else -1
  Points3f part;                        ///< [n, 3] part location in [0,1]^3; zero unless label 1
  std::size_t num_non_finite = 0;       ///< skipped non-finite points (labelled 0)
};

/// Computes Part-A2 part targets of `cloud` against `boxes` (box3.hpp convention, sizes > 0).
/// @param cloud any PointCloud, metres, same frame as the boxes
/// @param boxes ground-truth boxes; only centre, size and yaw are read
/// @param params see PartTargetParams
/// @throws ds3d::InvalidArgument for bad params, a box with a non-finite value or a size <= 0,
///         or a non-finite point when on_non_finite = kThrow
/// @note O(n m) for n points and m boxes, computed in double; deterministic.
template <PointCloud C>
[[nodiscard]] PartTargets part_a2_targets(const C& cloud, std::span<const Box3> boxes,
                                          const PartTargetParams& params = {}) {
  params.validate();
  for (std::size_t k = 0; k < boxes.size(); ++k) {
    const Box3& b = boxes[k];
    DS3D_CHECK(b.centre.allFinite() && b.size.allFinite() && std::isfinite(b.yaw),
               "ds3d::part_a2_targets: boxes[", k, "] has a non-finite value");
    DS3D_CHECK((b.size.array() > 0.0F).all(), "ds3d::part_a2_targets: boxes[", k,
               "] sizes must be > 0 (got ", b.size.transpose(), ")");
  }
  const std::size_t n = cloud::size(cloud);
  PartTargets out;
  out.label.assign(n, 0);
  out.box_index.assign(n, -1);
  out.part = Points3f::Zero(static_cast<Eigen::Index>(n), 3);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f pf = cloud::point(cloud, i);
    if (!cloud::is_finite(pf)) {
      DS3D_CHECK(params.on_non_finite == NonFinite::kSkip, "ds3d::part_a2_targets: point ", i,
                 " is not finite");
      ++out.num_non_finite;
      continue;
    }
    const Eigen::Vector3d p = pf.cast<double>();
    bool in_enlarged = false;
    for (std::size_t k = 0; k < boxes.size(); ++k) {
      const Box3& b = boxes[k];
      if (box::contains(b, p)) {
        const Eigen::Vector3d l = box::to_local(b, p);
        const Eigen::Vector3d t = l.cwiseQuotient(b.size.cast<double>()).array() + 0.5;
        out.part.row(static_cast<Eigen::Index>(i)) = t.cast<float>().transpose();
        out.box_index[i] = static_cast<std::int32_t>(k);
        out.label[i] = 1;
        break;
      }
      in_enlarged = in_enlarged || box::contains(b, p, params.extra_width);
    }
    if (out.label[i] == 0 && in_enlarged) out.label[i] = -1;
  }
  return out;
}

/// Overload for numpy-style (n, 3) float arrays (used by the Python binding).
[[nodiscard]] inline PartTargets part_a2_targets(Eigen::Ref<const Points3f> xyz,
                                                 std::span<const Box3> boxes,
                                                 const PartTargetParams& params = {}) {
  return part_a2_targets<Eigen::Ref<const Points3f>>(xyz, boxes, params);
}

}  // namespace ds3d
