// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Defines the Eigen-ABI symbol of this build (see include/ds3d/detail/abi_guard.hpp).
#include "ds3d/detail/abi_guard.hpp"

extern "C" const int DS3D_EIGEN_ABI_SYMBOL = 1;
