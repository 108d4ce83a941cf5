#!/usr/bin/env bash
# The DFSPH studies of docs/validation.md and docs/benchmarks.md, on the GPU
# machine after `tools/gpu-check.sh build`: Martin & Moyce front error against
# wall time for all three solvers in one call, the dam break's front, density
# error and iterations against the step's CFL and against the tolerance, the
# stress scenes that load a pressure solve (a deep tank, an impact) under all
# solvers, and the dam break to t = 1 s at three sizes (real-time factor).
# Results as CSV/JSON under $OUT.
set -uo pipefail
OUT=${OUT:-$PWD/gpu-out}
B=${B:-build-gpu}
mkdir -p "$OUT"
DEV="$(nvidia-smi --query-gpu=name --format=csv,noheader | head -1)"

echo "== Martin & Moyce, all solvers"
for solver in wcsph pbf dfsph; do
  python3 tools/validate.py run --sphray $B/sphray --backend cuda --device "$DEV" --resolutions ${RESOLUTIONS:-10,20,40,80} \
    --set sph.solver=$solver --out "$OUT/validation_cuda_$solver.json" | grep "a/"
done

SOLVER=dfsph
source "$(dirname "$0")/study-common.sh"
echo "== dfsph dam break to 0.3 s: CFL"
{ echo "$HDR"
  for dx in 0.00864 0.00432; do
    for cfl in 0.1 0.2 0.4 0.8; do dam "dx=$dx cfl=$cfl" sph.spacing=$dx sph.cfl=$cfl; done
  done; } | tee "$OUT/dfsph_cfl.csv"
echo "== dfsph dam break to 0.3 s: tolerance (both solves)"
{ echo "$HDR"
  for dx in 0.00864 0.00432; do
    for tol in 0.01 0.003 0.001 0.0003; do
      dam "dx=$dx tolerance=$tol" sph.spacing=$dx dfsph.tolerance=$tol dfsph.divergence_tolerance=$tol
    done
  done; } | tee "$OUT/dfsph_tolerance.csv"
echo "== stress: deep tank (100 layers) and impact, all solvers"
for scene in deep_tank impact; do
  for solver in wcsph pbf dfsph; do
    echo "-- $scene $solver"
    $B/sphray run scenes/stress/$scene.json --backend cuda --quiet --set sph.solver=$solver 2>&1 \
      | grep -E "simulated|constraint|pressure solve|max speed|error"
  done
done
echo "== dam break to 1 s (real-time factor of the simulation alone)"
for dx in 0.00864 0.00432 0.00272; do
  echo "-- dfsph dx=$dx"
  $B/sphray run scenes/dam_break.json --backend cuda --quiet --set sph.solver=dfsph --set sph.spacing=$dx \
    --set run.end_time=1.0 2>&1 | grep -E "simulated|wall time|pressure solve|max speed"
done
