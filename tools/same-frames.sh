#!/usr/bin/env bash
# Checks that a change left the simulation's results as they were: builds the
# revision REF (default HEAD) and the working tree, runs the dam break and the
# Martin & Moyce scene on the CPU backend with both, exporting every dataset
# (velocity, density, pressure, presence, the field), and compares the HDF5
# frames and walls with h5diff, bit for bit (no tolerance).
#   tools/same-frames.sh [REF]
# Needs h5diff (Debian/Ubuntu: hdf5-tools; installed when missing). Both runs
# use one OpenMP thread: the field's splats add into voxels atomically, and
# with several threads their order (so a float sum's last bit) varies from run
# to run.
set -euo pipefail
cd "$(dirname "$0")/.."
ref=${1:-HEAD}
work=$(mktemp -d /tmp/sphray-same-frames.XXXXXX)
trap 'git worktree remove --force "$work/ref-src" >/dev/null 2>&1 || true; rm -rf "$work"' EXIT

if ! command -v h5diff >/dev/null; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq hdf5-tools >/dev/null
fi

build() {  # source dir, build dir
  cmake -S "$1" -B "$2" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSPHRAY_CUDA=OFF -DSPHRAY_VIEWER=OFF \
    -DSPHRAY_TESTS=OFF >/dev/null
  ninja -C "$2" sphray >/dev/null
}
git worktree add --detach "$work/ref-src" "$ref" >/dev/null 2>&1
echo "building $ref and the working tree (CPU backend)"
build "$work/ref-src" "$work/ref-build"
build . "$work/new-build"

export OMP_NUM_THREADS=1
fields=velocity,density,pressure,presence,field
run() {  # exe, out prefix
  "$1" run scenes/dam_break.json --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.4 \
    --set run.output_interval=0.05 --export "$2_dam.h5" --export-fields "$fields" >/dev/null
  "$1" run scenes/validation/martin_moyce.json --backend cpu --quiet --set sph.spacing=0.0057 \
    --set run.end_time=0.2 --set run.output_interval=0.05 --export "$2_mm.h5" --export-fields "$fields" >/dev/null
}
run "$work/ref-build/sphray" "$work/ref"
run "$work/new-build/sphray" "$work/new"

status=0
for s in dam mm; do
  for group in /frames /boundary; do
    if h5diff -q "$work/ref_$s.h5" "$work/new_$s.h5" "$group" "$group"; then
      echo "same: $s $group"
    else
      echo "DIFFERENT: $s $group (h5diff $work/ref_$s.h5 $work/new_$s.h5 $group)"
      status=1
    fi
  done
done
exit $status
