#!/usr/bin/env bash
# One call on the GPU machine: configure with CUDA, build on all cores, run
# the cpu and gpu tests, the benchmarks and the CUDA validation runs, leaving
# JSON and the test log under $OUT (at most 8 files come back from the device
# tool; build logs stay in $B). Steps can be chosen:
#   tools/gpu-check.sh [build] [test] [sanitize] [main] [bench] [pbf] [pbf-study] [dfsph] [dfsph-study] [kernels] [field] [ncu-field]
#                      [export] [frame] [look]
#                      [render] [validate] [viewer] [compare]
#   (default: build test main bench validate; FIELD_SIZES picks the sizes of `field`; `compare` builds the
#   source tree in REF_TAR (git archive REV -o .ref/ref.tar, carried) and runs bench sim, field and frame
#   with it and with this tree in turn)
set -uo pipefail
OUT=${OUT:-$PWD/gpu-out}
mkdir -p "$OUT"
steps=${*:-build test main bench validate}
has() { [[ " $steps " == *" $1 "* ]]; }
B=build-gpu

# Debian packages the GPU machine lacks (stb), carried in .devdeps (apt-get download libstb-dev libstb0)
if ls .devdeps/*.deb > /dev/null 2>&1; then
  for f in .devdeps/*.deb; do dpkg -x "$f" /opt/deps; done
  export CPATH=/opt/deps/usr/include${CPATH:+:$CPATH} CMAKE_PREFIX_PATH=/opt/deps/usr${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}
  export LIBRARY_PATH=/opt/deps/usr/lib/x86_64-linux-gnu LD_LIBRARY_PATH=/opt/deps/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
fi
# Parallel HDF5 carried the same way (apt-get download libhdf5-openmpi-dev libhdf5-openmpi-103-1
# libhdf5-openmpi-hl-100 libhdf5-openmpi-cpp-103-1 libhdf5-openmpi-hl-cpp-100): its compiler
# wrapper names its own prefix, which the unpacked copy moves.
HDF5_ARGS=()
if [ -f /opt/deps/usr/bin/h5pcc.openmpi ]; then
  sed -i 's#^prefix="/usr"#prefix="/opt/deps/usr"#' /opt/deps/usr/bin/h5pcc.openmpi
  HDF5_ARGS=(-DHDF5_C_COMPILER_EXECUTABLE=/opt/deps/usr/bin/h5pcc.openmpi)
fi

if has build; then
  echo "== build"
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$OUT/gpu.txt"
  cmake -S . -B $B -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=90 -DSPHRAY_WERROR=ON "${HDF5_ARGS[@]}" \
    > "$B-configure.log" 2>&1 || { tail -30 "$B-configure.log"; exit 1; }
  grep 'sphray:' "$B-configure.log"
  ninja -C $B > "$B-build.log" 2>&1 || { grep -E 'error|Error' -A3 "$B-build.log" | head -60; exit 1; }
fi
if has test; then
  echo "== tests (${TEST_LABEL:-all})"
  ctest --test-dir $B --output-on-failure -j "${TEST_JOBS:-4}" ${TEST_LABEL:+-L $TEST_LABEL} 2>&1 | tee "$OUT/ctest.log" | tail -25
fi
if has sanitize; then
  echo "== compute-sanitizer on the gpu tests"
  # the hydrostatic study (about 60 s of simulation) would take hours under memcheck; its kernels are the dam break's
  compute-sanitizer --tool memcheck $B/tests/sphray_tests "[gpu]~*hydrostatic*" 2>&1 | tail -8 | tee "$OUT/sanitizer.log"
fi
if has main; then
  echo "== the README's main job (dam break) on this machine"
  # tools/setup.sh looks for tinyobjloader's header in /usr/include and would
  # try to install it; the device has no network, so the carried copy goes there.
  [ -f /usr/include/tiny_obj_loader.h ] || cp /opt/deps/usr/include/tiny_obj_loader.h /usr/include/ 2>/dev/null || true
  SPHRAY_BUILD_DIR=$B tools/dam-break.sh --quiet 2>&1 | grep -v -E '^\[|^ninja' | tail -12
fi
if has bench; then
  echo "== bench sim"
  $B/sphray bench sim --backend cuda --json "$OUT/bench_sim.json" 2>&1 | grep -v warm-up
  echo "== bench sim, h = 1.3 dx"
  $B/sphray bench sim --backend cuda --set sph.smoothing_ratio=1.3 --json "$OUT/bench_sim_h13.json" 2>&1 \
    | grep -v warm-up
fi
if has pbf; then
  echo "== bench sim, pbf, from t = 0.3 s of the dam break (the flow's steps)"
  $B/sphray bench sim --backend cuda --set sph.solver=pbf --from 0.3 --json "$OUT/bench_sim_pbf.json" 2>&1 | grep -v warm-up
  $B/sphray bench sim --backend cuda --from 0.3 --json "$OUT/bench_sim_wcsph_from.json" 2>&1 | grep -v warm-up
  $B/sphray bench sim --backend cuda --set sph.solver=pbf --from 0.3 --sizes 1M --kernels 2>&1 | grep -E "launches"
  echo "== bench frame --realtime, pbf"
  $B/sphray bench frame --backend cuda --sizes 125k,1M,4M --realtime --set sph.solver=pbf --json "$OUT/bench_frame_pbf.json" \
    2>&1 | grep -vE "simulating|sim .* ms"
fi
if has pbf-study; then
  OUT=$OUT B=$B tools/pbf-study.sh
fi
if has dfsph; then
  echo "== bench sim, all solvers, from t = 0.3 s of the dam break (the flow's steps)"
  for solver in dfsph pbf wcsph; do
    sizes=125k,1M,4M
    [ $solver = wcsph ] && sizes=125k,1M  # 4M: about 10,000 WCSPH steps to reach 0.3 s
    $B/sphray bench sim --backend cuda --set sph.solver=$solver --from 0.3 --sizes $sizes \
      --json "$OUT/bench_sim_$solver.json" 2>&1 | grep -v warm-up
  done
  $B/sphray bench sim --backend cuda --set sph.solver=dfsph --from 0.3 --sizes 1M --kernels 2>&1 | grep -E "launches"
  echo "== bench frame --realtime, dfsph"
  $B/sphray bench frame --backend cuda --sizes ${FRAME_SIZES:-125k,1M} --realtime --set sph.solver=dfsph \
    --json "$OUT/bench_frame_dfsph.json" 2>&1 | grep -vE "simulating|sim .* ms"
fi
if has dfsph-study; then
  OUT=$OUT B=$B tools/dfsph-study.sh
fi
if has kernels; then
  echo "== bench sim --kernels (ms per step by launch name)"
  $B/sphray bench sim --backend cuda --kernels --json "$OUT/bench_sim_kernels.json" 2>&1 | grep -v warm-up
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
if has look; then
  # docs/rendering.md's look figures at one commit: the wide frame at 125k and 1M as a clear film, the
  # defaults and the defaults with ellipsoids, and the 1M close-up with spheres (clear film) and with
  # ellipsoids: 8 PNGs (look_<film>_<particles>.png, close_<film>.png) in one $OUT/look.tar (the device
  # tool brings back 8 files), which tools/look_figures.py crops and stacks into docs/img on the workstation
  # (tar xf look.tar -C DIR; tools/look_figures.py DIR).
  echo "== look figures"
  CLEAR=(--set render.reflections=false --set 'render.absorption=[1.2,0.35,0.2]' --set 'render.tint=[0,0,0]')
  CLOSE=(--sizes 1M --warmup 0 --frames 2 --set 'render.eye=[1.05,-0.45,0.42]' --set 'render.target=[0.5,0.35,0.02]')
  look() {  # name, bench frame arguments...
    local name=$1 d
    shift
    d=$(mktemp -d)
    $B/sphray bench frame --backend cuda --png-dir "$d" "$@" > "$d.log" 2>&1 || { echo "$name: failed"; tail -5 "$d.log"; return; }
    for f in "$d"/bench_frame_*.png; do
      n=$(basename "$f" .png)
      n=${n#bench_frame_}
      case $name in close_*) cp "$f" "$L/$name.png" ;; *) cp "$f" "$L/look_${name}_$n.png" ;; esac
    done
    echo "$name: $(grep -E 'fps' "$d.log" | tail -2 | tr '\n' ' ')"
  }
  L=$(mktemp -d)
  look clear --sizes 125k,1M "${CLEAR[@]}"
  look defaults --sizes 125k,1M
  look ellipsoids --sizes 125k,1M --set field.kernel=anisotropic
  look close_spheres_clear "${CLOSE[@]}" "${CLEAR[@]}"
  look close_ellipsoids "${CLOSE[@]}" --set field.kernel=anisotropic
  tar cf "$OUT/look.tar" -C "$L" . && ls "$L"
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
if has viewer; then
  # The viewer in a real X window on the GPU: Xvfb + Mesa for the X server's GLX,
  # the NVIDIA GLX client (__GLX_VENDOR_LIBRARY_NAME=nvidia) so that the GL
  # context lives on the CUDA device and CUDA-OpenGL interop can work
  # (/work/.library/device/README.md). Carried: .gl (the GL loaders, unpacked
  # into / as that README says) and .viewerdeps (Debian's xvfb, Mesa, GLFW,
  # GLEW, Dear ImGui and their dependencies: apt-get download, see
  # docs/rendering.md), unpacked into /opt/gl; a separate build with the viewer.
  echo "== viewer under Xvfb (CUDA backend)"
  if ! ls .viewerdeps/*.deb > /dev/null 2>&1; then echo "no .viewerdeps carried: skipped"; else (
    G=/opt/gl
    for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
    for f in .gl/*.deb .devdeps/*.deb .viewerdeps/*.deb; do dpkg -x "$f" $G; done
    # Xvfb's compiled-in paths: xkbcomp, the XKB data, Mesa's DRI drivers
    [ -e /usr/bin/xkbcomp ] || ln -s $G/usr/bin/xkbcomp /usr/bin/xkbcomp
    [ -e /usr/share/X11/xkb ] || { mkdir -p /usr/share/X11; ln -s $G/usr/share/X11/xkb /usr/share/X11/xkb; }
    [ -e /usr/lib/x86_64-linux-gnu/dri ] || ln -s $G/usr/lib/x86_64-linux-gnu/dri /usr/lib/x86_64-linux-gnu/dri
    export PKG_CONFIG_PATH=$G/usr/lib/x86_64-linux-gnu/pkgconfig:$G/usr/share/pkgconfig PKG_CONFIG_SYSROOT_DIR=$G
    export CMAKE_PREFIX_PATH=$G/usr CPATH=$G/usr/include:$G/usr/include/stb LIBRARY_PATH=$G/usr/lib/x86_64-linux-gnu
    nv=$(ls -d /usr/local/nvidia/lib64 /usr/local/nvidia/lib 2>/dev/null | tr '\n' ':')
    export LD_LIBRARY_PATH=$G/usr/lib/x86_64-linux-gnu:$nv${LD_LIBRARY_PATH:-}
    export PATH=$G/usr/bin:$PATH  # pkgconf, Xvfb, xvfb-run, xauth
    ldconfig -p | grep -E 'libGLX_nvidia' | head -2
    echo "pkg-config: $(command -v pkg-config) $(pkg-config --modversion glfw3 glew imgui gl 2>&1 | tr '\n' ' ')"
    cmake -S . -B build-view -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=90 -DSPHRAY_VIEWER=ON \
      > build-view-configure.log 2>&1 || { tail -30 build-view-configure.log; exit 1; }
    grep 'sphray:' build-view-configure.log
    ninja -C build-view sphray > build-view.log 2>&1 || { grep -E 'error' -A3 build-view.log | head -40; exit 1; }
    export __GLX_VENDOR_LIBRARY_NAME=nvidia
    Xvfb :7 -screen 0 1920x1200x24 > "$OUT/xvfb.log" 2>&1 &
    xpid=$!
    sleep 3
    for size in ${VIEW_SIZES:-1280x720 1920x1080}; do
      echo "-- sphray view --backend cuda --size $size (the built-in scene, then scenes/dam_break.json)"
      DISPLAY=:7 timeout 120 build-view/sphray view --backend cuda --frames 120 --size $size \
        --screenshot "$OUT/view_cuda_$size.png" 2>&1 | tail -6
      DISPLAY=:7 timeout 120 build-view/sphray view scenes/dam_break.json --backend cuda --frames 120 --size $size 2>&1 | tail -3
    done
    echo "-- sphray view --backend cuda --size 1280x720 --resize 1600x900 (the pixel buffer re-registered at the new size)"
    DISPLAY=:7 timeout 120 build-view/sphray view --backend cuda --frames 30 --size 1280x720 --resize 1600x900 \
      --screenshot "$OUT/view_cuda_resized.png" 2>&1 | tail -3
    for dx in 0.0086 0.00432; do
      echo "-- sphray view scenes/dam_break.json --backend cuda --size 1920x1080 --substeps 5 --set sph.spacing=$dx"
      DISPLAY=:7 timeout 120 build-view/sphray view scenes/dam_break.json --backend cuda --frames 90 --size 1920x1080 \
        --substeps 5 --set sph.spacing=$dx --screenshot "$OUT/view_cuda_dam_$dx.png" 2>&1 | tail -3
    done
    kill $xpid; tail -5 "$OUT/xvfb.log"
  ) fi
fi
if has compare; then
  # The same benchmarks with the reference tree and this one, in turn on the
  # same machine (stage medians; the reference printed first in each pair).
  R=build-ref
  echo "== compare with ${REF_TAR:-.ref/ref.tar}: build"
  rm -rf ref-src && mkdir -p ref-src && tar -xf "${REF_TAR:-.ref/ref.tar}" -C ref-src
  if [ ! -x $R/sphray ]; then
    cmake -S ref-src -B $R -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=90 -DSPHRAY_TESTS=OFF \
      -DSPHRAY_VIEWER=OFF > $R-configure.log 2>&1 && ninja -C $R sphray > $R-build.log 2>&1 ||
      { tail -20 $R-build.log; exit 1; }
  fi
  for k in 1 2; do
    for exe in $R/sphray $B/sphray; do
      echo "-- bench sim 1M, $exe (run $k)"
      $exe bench sim --backend cuda --sizes 1M 2>&1 | grep -E '^ +[a-z]+ +[0-9]+ +(on|off) '
    done
  done | tee "$OUT/compare_sim.log"
  for exe in $R/sphray $B/sphray; do
    echo "-- bench field ${CMP_FIELD_SIZES:-1M,4M}, $exe"
    $exe bench field --backend cuda --sizes "${CMP_FIELD_SIZES:-1M,4M}" 2>&1 | grep -E '^ +[0-9]+ +[0-9]+\^3'
  done | tee "$OUT/compare_field.log"
  for exe in $R/sphray $B/sphray; do
    echo "-- bench frame 125k,1M, $exe"
    $exe bench frame --backend cuda --sizes 125k,1M 2>&1 | grep -E '^ +[0-9]+ +[0-9]+x[0-9]+'
  done | tee "$OUT/compare_frame.log"
fi
