#!/usr/bin/env bash
# The test command of the README: set up, build, run every test. `gpu` tests
# are reported as skipped where no CUDA device is present. Extra arguments go
# to ctest (e.g. -L cpu, -R grid).
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh
ctest --test-dir "${SPHRAY_BUILD_DIR:-build}" --output-on-failure "$@"
