#!/usr/bin/env bash
# Installs what sphray needs to build and test (Debian 12 / Ubuntu 24.04),
# configures and builds it in build/. Safe to run again: installs only what
# is missing and rebuilds only what changed.
#   SPHRAY_BUILD_DIR (default build), SPHRAY_CMAKE_ARGS (extra cmake flags)
set -euo pipefail
cd "$(dirname "$0")/.."

pkgs=(cmake ninja-build g++ nlohmann-json3-dev libcli11-dev catch2 python3-matplotlib)
# Thrust/CUB for the CPU backend come with the CUDA toolkit; without it, from Debian.
[ -d /usr/local/cuda/include/cccl/thrust ] || pkgs+=(libthrust-dev)
missing=()
for p in "${pkgs[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  echo "sphray setup: installing ${missing[*]}"
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

BUILD=${SPHRAY_BUILD_DIR:-build}
# shellcheck disable=SC2086
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release ${SPHRAY_CMAKE_ARGS:-} | grep -E 'sphray:|Error' || true
ninja -C "$BUILD"
