#!/usr/bin/env bash
# Installs what sphray needs to build and test (Debian 12 / Ubuntu 24.04),
# configures and builds it in build/. Safe to run again: installs only what
# is missing and rebuilds only what changed.
#   SPHRAY_BUILD_DIR (default build), SPHRAY_CMAKE_ARGS (extra cmake flags)
set -euo pipefail
cd "$(dirname "$0")/.."

# Each need is probed (a command or a header), so a machine that has it from
# elsewhere (a CUDA toolkit, a newer cmake) is left alone; only what is missing
# is installed from the distribution.
missing=()
need() { eval "$2" >/dev/null 2>&1 || missing+=("$1"); }
need cmake "command -v cmake"
need ninja-build "command -v ninja"
need g++ "command -v g++"
need nlohmann-json3-dev "test -f /usr/include/nlohmann/json.hpp"
need libcli11-dev "test -f /usr/include/CLI/CLI.hpp"
need catch2 "test -f /usr/include/catch2/catch.hpp || test -f /usr/include/catch2/catch_all.hpp"
# Thrust/CUB for the CPU backend come with the CUDA toolkit; without it, from Debian.
need libthrust-dev "test -d /usr/local/cuda/include/cccl/thrust || test -f /usr/include/thrust/version.h"
need libeigen3-dev "test -f /usr/include/eigen3/Eigen/Core"
need libtinyobjloader-dev "test -f /usr/include/tiny_obj_loader.h"
need libhdf5-dev "test -f /usr/include/hdf5/serial/hdf5.h || test -f /usr/include/hdf5.h"
# MPI for runs over several ranks (mpirun -np R sphray run ...; dist/) and their tests.
need libopenmpi-dev "test -f /usr/lib/x86_64-linux-gnu/openmpi/include/mpi.h || command -v mpicxx"
need openmpi-bin "command -v mpirun"
# stb (PNG): also found under a prefix in CMAKE_PREFIX_PATH (the GPU machine carries it: tools/gpu-check.sh, .devdeps)
has_stb() {
  local p
  for p in /usr $(echo "${CMAKE_PREFIX_PATH:-}" | tr ':' ' '); do test -f "$p/include/stb/stb_image_write.h" && return 0; done
  return 1
}
need libstb-dev has_stb
# matplotlib only draws the validation plots (tools/validate.py report).
need python3-matplotlib "python3 -c 'import matplotlib'"
# The viewer (sphray view) and its test under Xvfb: wanted, not required. A
# machine without them (or without a network, like the GPU machine) builds
# everything else; the viewer's test then says it was not run.
wanted=()
want() { eval "$2" >/dev/null 2>&1 || wanted+=("$1"); }
want pkg-config "command -v pkg-config"
want libglfw3-dev "test -f /usr/include/GLFW/glfw3.h"
want libglew-dev "test -f /usr/include/GL/glew.h"
want libimgui-dev "test -f /usr/include/imgui/imgui.h"
want xvfb "command -v xvfb-run"
want xauth "command -v xauth"
# Parallel HDF5 (every rank of a run over several writes its rows of the
# export, dist/rank_export.h): wanted too; without it rank 0 writes the export.
parallel_h5=()
test -f /usr/include/hdf5/openmpi/hdf5.h || parallel_h5+=(libhdf5-openmpi-dev)
SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
if [ ${#missing[@]} -gt 0 ] || [ ${#wanted[@]} -gt 0 ] || [ ${#parallel_h5[@]} -gt 0 ]; then
  $SUDO apt-get update -qq || true
fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "sphray setup: installing ${missing[*]}"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi
if [ ${#wanted[@]} -gt 0 ]; then
  echo "sphray setup: installing for the viewer: ${wanted[*]}"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${wanted[@]}" >/dev/null ||
    echo "sphray setup: could not install ${wanted[*]}: building without the viewer"
fi
if [ ${#parallel_h5[@]} -gt 0 ]; then
  echo "sphray setup: installing parallel HDF5: ${parallel_h5[*]}"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${parallel_h5[@]}" >/dev/null ||
    echo "sphray setup: could not install ${parallel_h5[*]}: exports of runs over several ranks go through rank 0"
fi

BUILD=${SPHRAY_BUILD_DIR:-build}
# shellcheck disable=SC2086
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release ${SPHRAY_CMAKE_ARGS:-} | grep -E 'sphray:|Error' || true
ninja -C "$BUILD"
