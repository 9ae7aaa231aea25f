#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Installs the build in BUILD_DIR into a temporary prefix and builds examples/consumer/,
# examples/include_in_slam/ and examples/cluster_bench/ against it with find_package(ds3d), then
# runs them (include_in_slam exits non-zero when the person's keypoints are not removed;
# cluster_bench runs its smallest cases once). Also checks that a header-only install (no SLAM)
# serves ds3d::core and ds3d::htx (the shipped detector, no OpenCV, no Ceres), builds and runs
# include_in_slam against it, and that
# asking it for COMPONENTS slam fails cleanly at configure time.
# The consumer contract (docs/install.md), from the build tree without installing
# (-Dds3d_DIR=BUILD_DIR): tests/consumer/ builds <ds3d/ds3d.hpp> with plain x86-64 flags next to
# a static Eigen library built with other flags, whatever SIMD level ds3d has, and checks that
# no ds3d target propagates compile flags; the compiled ds3d::htx links with ds3d::abi, and
# without it fails to link when the library's Eigen ABI differs; a core-only find_package(ds3d)
# configures with OpenCV and Ceres hidden; <ds3d/ds3d.hpp> includes every core header.
# DS3D_EXTRA_CONSUMERS="dir ..." adds more examples/<dir> projects to the build loop.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${1:-build}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "consumer: <ds3d/ds3d.hpp> covers the core"
for h in $(cd include && find ds3d -name '*.hpp' ! -path 'ds3d/detail/*' ! -path 'ds3d/htx/*' \
             ! -path 'ds3d/slam/*' ! -name ds3d.hpp | sort); do
  grep -q "#include \"${h}\"" include/ds3d/ds3d.hpp || {
    echo "consumer: FAILED: include/ds3d/ds3d.hpp lacks ${h}" >&2
    exit 1
  }
done

echo "consumer: tests/consumer against the build tree (-Dds3d_DIR=${BUILD_DIR}, not installed)"
cmake -S tests/consumer -B "${tmp}/build-contract" -G Ninja -Dds3d_DIR="$(cd "${BUILD_DIR}" && pwd)" \
  >"${tmp}/contract.log" || { cat "${tmp}/contract.log"; exit 1; }
cmake --build "${tmp}/build-contract" >/dev/null
"${tmp}/build-contract/umbrella_app"
"${tmp}/build-contract/htx_guard"
simd=$(sed -n 's/^set(ds3d_SIMD_LEVEL "\(.*\)").*/\1/p' "${BUILD_DIR}/ds3dConfig.cmake")
if [ "${simd}" = avx2 ]; then
  if cmake --build "${tmp}/build-contract" --target htx_guard_mismatch >"${tmp}/guard.log" 2>&1; then
    echo "consumer: FAILED: plain-flag code linked the avx2 ds3d::htx without ds3d::abi" >&2
    exit 1
  fi
  grep -q "ds3d_eigen_abi_heap16_fixed16" "${tmp}/guard.log"
  echo "consumer: plain-flag code calling the avx2 ds3d::htx without ds3d::abi fails to link"
fi
cmake -S examples/consumer -B "${tmp}/build-tree-slam" -G Ninja \
  -Dds3d_DIR="$(cd "${BUILD_DIR}" && pwd)" -DCONSUMER_COMPONENTS=slam >/dev/null

echo "consumer: installing ${BUILD_DIR} into ${tmp}/prefix"
cmake --install "${BUILD_DIR}" --prefix "${tmp}/prefix" >/dev/null
for example in consumer include_in_slam cluster_bench ${DS3D_EXTRA_CONSUMERS:-}; do
  echo "consumer: building examples/${example} against the installed package"
  cmake -S "examples/${example}" -B "${tmp}/build-${example}" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_PREFIX_PATH="${tmp}/prefix" -DCONSUMER_COMPONENTS=slam --no-warn-unused-cli >/dev/null
  cmake --build "${tmp}/build-${example}" >/dev/null
done
"${tmp}/build-consumer/app"
"${tmp}/build-consumer/app_core"
"${tmp}/build-consumer/app_htx" "${tmp}/prefix/share/ds3d/models/htx_lite_fast.safetensors"
"${tmp}/build-include_in_slam/include_in_slam"
"${tmp}/build-cluster_bench/cluster_bench" '--benchmark_filter=/n:(1000|100)(/|$)' \
  --benchmark_min_time=0.01

echo "consumer: core-only find_package(ds3d) with OpenCV and Ceres hidden"
cmake -S tests/consumer -B "${tmp}/build-no-opencv" -G Ninja -DCMAKE_PREFIX_PATH="${tmp}/prefix" \
  -DCMAKE_DISABLE_FIND_PACKAGE_OpenCV=ON -DCMAKE_DISABLE_FIND_PACKAGE_Ceres=ON \
  -DCMAKE_DISABLE_FIND_PACKAGE_yaml-cpp=ON >/dev/null

echo "consumer: header-only install (DS3D_BUILD_SLAM=OFF)"
cmake -S . -B "${tmp}/core-build" -G Ninja -DDS3D_BUILD_SLAM=OFF -DDS3D_BUILD_TESTS=OFF \
  -DDS3D_BUILD_BENCH=OFF -DDS3D_BUILD_PYTHON=OFF -DDS3D_BUILD_TOOLS=OFF \
  -DDS3D_BUILD_EXAMPLES=OFF >/dev/null
cmake --build "${tmp}/core-build" --target ds3d_htx >/dev/null  # the only compiled part
cmake --install "${tmp}/core-build" --prefix "${tmp}/core-prefix" >/dev/null
cmake -S examples/consumer -B "${tmp}/build-core" -G Ninja -DCMAKE_PREFIX_PATH="${tmp}/core-prefix" \
  -DCONSUMER_CORE_ONLY=ON >/dev/null
cmake --build "${tmp}/build-core" >/dev/null
"${tmp}/build-core/app_core"
# ds3d::htx from the same install: the shipped detector with Eigen only.
"${tmp}/build-core/app_htx" "${tmp}/core-prefix/share/ds3d/models/htx_lite_fast.safetensors"
if ldd "${tmp}/build-core/app_htx" | grep -Eq 'opencv|ceres'; then
  echo "consumer: FAILED: app_htx (ds3d::htx) links OpenCV or Ceres" >&2
  exit 1
fi
echo "consumer: ds3d::htx runs the shipped detector without OpenCV or Ceres"
cmake -S examples/include_in_slam -B "${tmp}/build-core-slam-example" -G Ninja \
  -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="${tmp}/core-prefix" >/dev/null
cmake --build "${tmp}/build-core-slam-example" >/dev/null
"${tmp}/build-core-slam-example/include_in_slam" >/dev/null
echo "consumer: include_in_slam builds and passes against the header-only install"
if cmake -S examples/consumer -B "${tmp}/build-core-slam" -G Ninja \
     -DCMAKE_PREFIX_PATH="${tmp}/core-prefix" -DCONSUMER_CORE_ONLY=ON -DCONSUMER_COMPONENTS=slam \
     >"${tmp}/slam.log" 2>&1; then
  echo "consumer: FAILED: COMPONENTS slam was accepted by a build without SLAM" >&2
  exit 1
fi
grep -q "ds3d" "${tmp}/slam.log"
echo "consumer: COMPONENTS slam correctly refused by the header-only install"
echo "consumer: OK"
