#!/usr/bin/env bash
# The test command of the README: set up, build, run every test, one ctest
# job per core (CTEST_PARALLEL_LEVEL overrides). `gpu` tests are reported as
# skipped where no CUDA device is present. Extra arguments go to ctest (e.g.
# -L cpu, -LE slow, -R grid).
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh
export CTEST_PARALLEL_LEVEL=${CTEST_PARALLEL_LEVEL:-$(nproc)}
ctest --test-dir "${SPHRAY_BUILD_DIR:-build}" --output-on-failure "$@"
