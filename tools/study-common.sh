# Shared by the solver studies (tools/pbf-study.sh, tools/dfsph-study.sh):
# one dam-break run of $SOLVER to t = 0.3 s on the CUDA backend, printed as a
# CSV row ($HDR): front at 0.3 s, the summary's density error, iterations,
# wall time and real-time factor. Source it with B (the build) set.
dam() {  # label, then --set arguments
  local label=$1; shift
  local sets=()
  for kv in "$@"; do sets+=(--set "$kv"); done
  rm -f /tmp/s.json /tmp/m.csv
  $B/sphray run scenes/dam_break.json --backend cuda --quiet --set sph.solver=$SOLVER --set run.end_time=0.3 \
    --set run.output_interval=0.3 "${sets[@]}" --metrics-csv /tmp/m.csv --summary-json /tmp/s.json > /dev/null 2>&1
  [ -s /tmp/s.json ] && grep -q '"completed"' /tmp/s.json || { echo "$label,stopped (diverged)"; return; }
  python3 - "$label" <<'PY'
import csv, json, sys
s = json.load(open('/tmp/s.json')); rows = list(csv.DictReader(open('/tmp/m.csv')))
c = s.get('constraint', {})
print(f"{sys.argv[1]},{s['fluid_start']},{s['steps']},{s['mean_dt_s']*1e3:.3f},{float(rows[-1]['front_m']):.4f},"
      f"{100*c.get('density_error_mean',0):.3f},{100*c.get('density_error_max',0):.2f},{s['max_speed_m_s']:.2f},"
      f"{s['wall_s']:.3f},{s['realtime_factor']:.3f},{c.get('iterations_mean',0):.2f},"
      f"{c.get('divergence_iterations',{}).get('mean',0):.2f}")
PY
}
HDR="case,particles,steps,mean_dt_ms,front_0.3s_m,density_error_mean_pct,density_error_max_pct,max_speed_m_s,wall_s,realtime,iterations_mean,divergence_iterations_mean"
