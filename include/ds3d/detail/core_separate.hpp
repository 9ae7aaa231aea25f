// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// DS3D_CORE_SEPARATE: the heavy core entry points compiled once per target, not in every TU.
#pragma once

// Defined (target-wide) by the CMake target ds3d::core_separate, which also adds
// ds3d_core_separate.cpp (DS3D_CORE_IMPLEMENTATION) to the consumer's target: HDBSCAN and the
// dynamic filter are then declared, not defined, in the consumer's translation units, and
// voxel_grid() on Points3f / Eigen::Ref<const Points3f> / std::vector<Eigen::Vector3f> is an
// extern template. Every file of a target must agree, so never define it per file.
#if defined(DS3D_CORE_SEPARATE)
#define DS3D_CORE_INLINE
#else
#define DS3D_CORE_INLINE inline
#endif
