#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# Installs the Debian packages ds3d needs, and only those that are missing (idempotent: a no-op
# when everything is there). Runs apt-get as root, or through sudo when available.
# Usage: scripts/install-deps.sh [--check]   (--check: list what is missing and exit 1 if any)
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libnanoflann-dev libopencv-dev libceres-dev libyaml-cpp-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  pybind11-dev python3-dev python3-pybind11 python3-numpy python3-pytest python3-matplotlib
  python3-setuptools python3-pip python3-wheel python3-venv
  clang-format clang-tidy ccache
)
# Per-component package lists: every non-comment word in scripts/deps/*.txt.
for list in "$(dirname "$0")"/deps/*.txt; do
  [[ -f "$list" ]] || continue
  while read -r line; do
    line=${line%%#*}
    for word in $line; do PACKAGES+=("$word"); done
  done <"$list"
done
# Extra packages requested by the caller (e.g. make bench-compare adds libopen3d-dev libpcl-dev).
if [[ -n "${DS3D_EXTRA_PACKAGES:-}" ]]; then
  read -r -a extra <<<"${DS3D_EXTRA_PACKAGES}"
  PACKAGES+=("${extra[@]}")
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install-deps: all ${#PACKAGES[@]} Debian packages present"
  exit 0
fi
echo "install-deps: missing Debian packages: ${missing[*]}"
if [[ "${1:-}" == "--check" ]]; then
  exit 1
fi

if [[ $(id -u) -eq 0 ]]; then
  SUDO=()
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  SUDO=(sudo -n)
else
  echo "install-deps: error: installing needs root. Run as root, give this user passwordless sudo," >&2
  echo "  or install them yourself:  sudo apt-get install ${missing[*]}" >&2
  exit 1
fi

export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -qq
"${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install-deps: installed ${#missing[@]} packages"
