#!/usr/bin/env bash
# One call on the GPU machine (see shared/device/README.md): configure with CUDA,
# build on all cores, run the cpu and gpu tests, the benchmarks and the CUDA
# validation runs, leaving JSON and the test log under $OUT (at most 8 files
# come back from the device tool; build logs stay in $B). Steps can be chosen:
#   tools/gpu-check.sh [build] [test] [sanitize] [main] [bench] [field] [ncu-field] [export] [frame] [render] [validate]
#   (default: build test main bench validate; FIELD_SIZES picks the sizes of `field`)
set -uo pipefail
OUT=${OUT:-$PWD/gpu-out}
mkdir -p "$OUT"
steps=${*:-build test main bench validate}
has() { [[ " $steps " == *" $1 "* ]]; }
B=build-gpu

# Debian packages the GPU machine lacks (stb), carried in .devdeps (shared/device/README.md)
if ls .devdeps/*.deb > /dev/null 2>&1; then
  for f in .devdeps/*.deb; do dpkg -x "$f" /opt/deps; done
  export CPATH=/opt/deps/usr/include${CPATH:+:$CPATH} CMAKE_PREFIX_PATH=/opt/deps/usr${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}
  export LIBRARY_PATH=/opt/deps/usr/lib/x86_64-linux-gnu LD_LIBRARY_PATH=/opt/deps/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
fi

if has build; then
  echo "== build"
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$OUT/gpu.txt"
  cmake -S . -B $B -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=90 -DSPHRAY_WERROR=ON \
    > "$B-configure.log" 2>&1 || { tail -30 "$B-configure.log"; exit 1; }
  grep 'sphray:' "$B-configure.log"
  ninja -C $B > "$B-build.log" 2>&1 || { grep -E 'error|Error' -A3 "$B-build.log" | head -60; exit 1; }
fi
if has test; then
  echo "== tests (${TEST_LABEL:-all})"
  ctest --test-dir $B --output-on-failure ${TEST_LABEL:+-L $TEST_LABEL} 2>&1 | tee "$OUT/ctest.log" | tail -25
fi
if has sanitize; then
  echo "== compute-sanitizer on the gpu tests"
  compute-sanitizer --tool memcheck $B/tests/sphray_tests "[gpu]" 2>&1 | tail -8 | tee "$OUT/sanitizer.log"
fi
if has main; then
  echo "== the README's main job (dam break) on this machine"
  SPHRAY_BUILD_DIR=$B tools/dam-break.sh --quiet 2>&1 | grep -v -E '^\[|^ninja' | tail -12
fi
if has bench; then
  echo "== bench sim"
  $B/sphray bench sim --backend cuda --json "$OUT/bench_sim.json" 2>&1 | grep -v warm-up
  echo "== bench sim, h = 1.3 dx"
  $B/sphray bench sim --backend cuda --set sph.smoothing_ratio=1.3 --json "$OUT/bench_sim_h13.json" 2>&1 \
    | grep -v warm-up
fi
if has field; then
  echo "== bench field (${FIELD_SIZES:-all sizes})"
  $B/sphray bench field --backend cuda ${FIELD_SIZES:+--sizes $FIELD_SIZES} \
    --json "$OUT/bench_field${FIELD_TAG:-}.json" 2>&1
fi
if has ncu-field; then
  echo "== ncu: field kernels at ${NCU_SIZE:-1M} particles"
  ncu --kernel-name-base demangled -k regex:'NaiveSplat|PresenceSplat|CoarseFill|MarkOccupied|GatherField' -c 30 \
    --section SpeedOfLight --section MemoryWorkloadAnalysis --section LaunchStats --section Occupancy \
    $B/sphray bench field --backend cuda --sizes "${NCU_SIZE:-1M}" --warmup 0 --frames 1 \
    > "$OUT/ncu_field.txt" 2>&1
  grep -E 'for_each_index_kernel|Duration|Memory Throughput|DRAM Throughput|Compute \(SM\) Throughput|L2 Cache Throughput' \
    "$OUT/ncu_field.txt" | sed 's/void sphray::cuda_backend::for_each_index_kernel/kernel/' | cut -c1-160 | head -60
fi
if has export; then
  echo "== export overhead: 1M-particle dam break, positions every frame (5 substeps), with and without --export"
  S="scenes/bench/dam_break.json --backend cuda --quiet --set sph.spacing=0.00432 --set run.end_time=0.1 --set run.output_interval=0.0006"
  for k in 1 2; do
    echo "-- without export (run $k)"; $B/sphray run $S | grep -E "simulated|wall time"
    echo "-- with --export (run $k)"; $B/sphray run $S --export /tmp/sphray_export_bench.h5 | grep -E "simulated|wall time|export "
    rm -f /tmp/sphray_export_bench.h5 /tmp/sphray_export_bench.xmf
  done
fi
if has frame; then
  echo "== bench frame (${FRAME_SIZES:-125k,1M}): substeps + field + render, 1920x1080, 4 interfaces"
  $B/sphray bench frame --backend cuda --sizes "${FRAME_SIZES:-125k,1M}" ${FRAME_ARGS:-} --png-dir "${PNG_DIR:-$OUT}" \
    --json "$OUT/bench_frame${FRAME_TAG:-}.json" 2>&1
fi
if has render; then
  echo "== bench render: PSNR against a fine reference vs render time (${RENDER_SIZE:-1M})"
  $B/sphray bench render --backend cuda --size "${RENDER_SIZE:-1M}" --width 1920 --height 1080 ${RENDER_ARGS:-} \
    --png-dir "${PNG_DIR:-$OUT}" --json "$OUT/bench_render.json" 2>&1
fi
if has validate; then
  echo "== validation (cuda)"
  python3 tools/validate.py run --sphray $B/sphray --backend cuda --device "$(head -1 "$OUT/gpu.txt" 2>/dev/null | cut -d, -f1)" \
    --resolutions "${RESOLUTIONS:-10,20,40}" --timeout "${VALIDATE_TIMEOUT:-240}" --out "$OUT/validation_cuda.json"
fi
