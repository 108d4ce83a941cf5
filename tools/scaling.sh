#!/usr/bin/env bash
# Weak and strong scaling of the dam break over several GPUs (mpirun, one
# rank per GPU, NCCL between them; docs/benchmarks.md, "Scale-out"). Each run
# starts at t = 0 and takes about STEPS steps (dt from the scene's CFL, which
# scales with the spacing); ms per step is the run's wall time (after setup)
# over its steps, the exchange's ms the solver's stage time (CUDA events).
# A one-GPU run is the ordinary run (no MPI).
#   tools/scaling.sh [BUILD_DIR]
#   env: GPUS="1 2" (rank counts), WEAK="1 4" (millions per GPU), STRONG="4 8"
#   (millions in all), STEPS=150, SOLVER=wcsph (or pbf, dfsph), EXTRA (more `run` arguments, e.g.
#   "--rebalance-every 10"), OUT (default ./scaling-out)
set -euo pipefail
B=${1:-build}
OUT=${OUT:-$PWD/scaling-out}
mkdir -p "$OUT"
# (an empty WEAK or STRONG runs none of that kind)
GPUS=${GPUS:-"1 2"} WEAK=${WEAK-"1 4"} STRONG=${STRONG-"4 8"} STEPS=${STEPS:-150} SOLVER=${SOLVER:-wcsph}
# the step at 4.32 mm, which scales with the spacing: WCSPH's acoustic one; PBF's and DFSPH's
# (the flow CFL; PBF's depth limit, then its error-sized step) about 1 ms over the first steps
case $SOLVER in wcsph) DT=0.11e-3 ;; pbf | dfsph) DT=1.0e-3 ;; *) echo "SOLVER: wcsph, pbf or dfsph"; exit 2 ;; esac
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export NCCL_NVLS_ENABLE=${NCCL_NVLS_ENABLE:-0}  # no NVLink multicast (shared machines)
scene=scenes/dam_break.json
results="$OUT/scaling.jsonl"
: > "$results"
run() {  # kind millions ranks
  local kind=$1 m=$2 r=$3
  # the dam break's 0.4 x 0.67 x 0.3 m column holds m million particles at this spacing
  local dx end name
  dx=$(python3 -c "print(f'{(0.0804 / ($m * 1e6)) ** (1 / 3):.6f}')")
  end=$(python3 -c "print(f'{$STEPS * $DT * $dx / 4.32e-3:.6f}')")
  name="${SOLVER}_${kind}_${m}M_${r}gpu"
  local cmd=("$B/sphray" run "$scene" --backend cuda --quiet --set "sph.solver=$SOLVER" --set "sph.spacing=$dx" --set "run.end_time=$end"
             --set "run.output_interval=$end" --summary-json "$OUT/$name.json" ${EXTRA:-})
  if [ "$r" -gt 1 ]; then cmd=(mpirun -np "$r" -x NCCL_NVLS_ENABLE "${cmd[@]}"); fi
  "${cmd[@]}" > "$OUT/$name.log" 2>&1 || { echo "$name failed:"; tail -5 "$OUT/$name.log"; return 1; }
  python3 - "$OUT/$name.json" "$kind" "$m" "$r" "$dx" >> "$results" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
s = j.get("stage_ms", {})
print(json.dumps({"solver": j.get("solver", ""), "kind": sys.argv[2], "millions": float(sys.argv[3]), "gpus": int(sys.argv[4]),
                  "spacing_m": float(sys.argv[5]), "particles": j["fluid_start"], "steps": j["steps"],
                  "ms_per_step": 1e3 * j["wall_s"] / j["steps"], "exchange_ms": s.get("exchange", 0.0),
                  "iterations_mean": j.get("constraint", {}).get("iterations_mean"),
                  "stage_ms_by_rank": j.get("stage_ms_by_rank", []),
                  "stage_ms": s}))
PY
}
for g in $GPUS; do
  for m in $WEAK; do run weak "$(python3 -c "print($m * $g)")" "$g"; done
  for m in $STRONG; do run strong "$m" "$g"; done
done
python3 - "$results" "$OUT/scaling.json" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
base = {}
for r in rows:
    if r["gpus"] == 1:
        base[(r["kind"], r["millions"])] = r["ms_per_step"]
out = []
print("| kind | particles | GPUs | ms/step | exchange ms | efficiency |")
print("| --- | --- | --- | --- | --- | --- |")
for r in rows:
    per = r["millions"] / r["gpus"] if r["kind"] == "weak" else r["millions"]
    ref = base.get(("weak", per)) if r["kind"] == "weak" else base.get(("strong", r["millions"]))
    # weak: t(1 GPU, the same particles per GPU) / t(n); strong: t(1) / (n t(n))
    eff = None if ref is None else (ref / r["ms_per_step"] if r["kind"] == "weak" else ref / (r["gpus"] * r["ms_per_step"]))
    r["efficiency"] = eff
    out.append(r)
    print(f"| {r['kind']} | {r['particles']/1e6:.2f}M | {r['gpus']} | {r['ms_per_step']:.3f} | {r['exchange_ms']:.3f} | "
          + ("-" if eff is None else f"{100 * eff:.0f}%") + " |")
json.dump(out, open(sys.argv[2], "w"), indent=1)
PY
