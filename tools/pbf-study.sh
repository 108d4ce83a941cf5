#!/usr/bin/env bash
# The PBF studies of docs/validation.md and docs/benchmarks.md, on the GPU
# machine after `tools/gpu-check.sh build`: Martin & Moyce front error against
# wall time for both solvers, the dam break's front and density error against
# the step's CFL and against iterations, and the dam break to t = 1 s at three
# sizes (real-time factor). Results as CSV/JSON under $OUT.
set -uo pipefail
OUT=${OUT:-$PWD/gpu-out}
B=${B:-build-gpu}
mkdir -p "$OUT"
DEV="$(nvidia-smi --query-gpu=name --format=csv,noheader | head -1)"

echo "== Martin & Moyce, both solvers"
for solver in wcsph pbf; do
  python3 tools/validate.py run --sphray $B/sphray --backend cuda --device "$DEV" --resolutions ${RESOLUTIONS:-10,20,40,80} \
    --set sph.solver=$solver --out "$OUT/validation_cuda_$solver.json" | tail -5
done

SOLVER=pbf
source "$(dirname "$0")/study-common.sh"
echo "== dam break to 0.3 s: CFL (depth limit and error-sized step off, max_dt 0.1 s)"
{ echo "$HDR"
  for dx in 0.00864 0.00432; do
    for cfl in 0.5 1 2 4 8; do dam "dx=$dx cfl=$cfl" sph.spacing=$dx sph.cfl=$cfl pbf.depth_error=0 pbf.step_error=0 run.max_dt=0.1; done
    dam "dx=$dx default" sph.spacing=$dx
  done; } | tee "$OUT/pbf_cfl.csv"
echo "== dam break to 0.3 s: iterations (defaults otherwise)"
{ echo "$HDR"
  for dx in 0.00864 0.00432; do
    for it in 1 2 3 4 6 8; do dam "dx=$dx iterations=$it" sph.spacing=$dx pbf.iterations=$it; done
  done; } | tee "$OUT/pbf_iterations.csv"
echo "== dam break to 1 s: the error-sized step (pbf.step_error; 0: the depth limit alone)"
{ echo "case,particles,steps,mean_dt_ms,density_error_mean_pct,density_error_max_pct,max_speed_m_s,wall_s,realtime,front_0.3s_m"
  for dx in 0.00864 0.00432 0.00272; do
    errors="0 0.003 0.005 0.007 0.01"
    [ $dx = 0.00272 ] && errors="0 0.005"
    for e in $errors; do
      $B/sphray run scenes/dam_break.json --backend cuda --quiet --set sph.solver=pbf --set sph.spacing=$dx \
        --set run.end_time=1.0 --set pbf.step_error=$e --summary-json /tmp/s.json > /dev/null 2>&1
      rm -f /tmp/m.csv
      $B/sphray run scenes/dam_break.json --backend cuda --quiet --set sph.solver=pbf --set sph.spacing=$dx \
        --set run.end_time=0.3 --set run.output_interval=0.3 --set pbf.step_error=$e --metrics-csv /tmp/m.csv > /dev/null 2>&1
      python3 - "dx=$dx step_error=$e" <<'PY'
import csv, json, sys
s = json.load(open('/tmp/s.json')); c = s.get('constraint', {})
rows = list(csv.DictReader(open('/tmp/m.csv')))
print(f"{sys.argv[1]},{s['fluid_start']},{s['steps']},{s['mean_dt_s']*1e3:.3f},{100*c.get('density_error_mean',0):.3f},"
      f"{100*c.get('density_error_max',0):.2f},{s['max_speed_m_s']:.2f},{s['wall_s']:.3f},{s['realtime_factor']:.3f},"
      f"{float(rows[-1]['front_m']):.4f}")
PY
    done
  done; } | tee "$OUT/pbf_step_error.csv"
echo "== dam break to 1 s, both solvers (real-time factor of the simulation alone)"
for dx in 0.00864 0.00432 0.00272; do
  solvers="pbf wcsph"
  [ $dx = 0.00272 ] && solvers=pbf  # WCSPH at 4M: about 14,000 steps for one second
  for solver in $solvers; do
    echo "-- $solver dx=$dx"
    $B/sphray run scenes/dam_break.json --backend cuda --quiet --set sph.solver=$solver --set sph.spacing=$dx \
      --set run.end_time=1.0 2>&1 | grep -E "simulated|wall time|constraint|max speed"
  done
done
