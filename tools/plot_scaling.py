#!/usr/bin/env python3
"""Plot of tools/scaling.sh results (docs/benchmarks.md, "Scale-out").

  plot_scaling.py docs/bench/scaling_2gpu_64M.json docs/bench/scaling_4gpu.json --png docs/scaling.png

(a later file's run of the same solver, kind, size and GPU count replaces an
earlier one's; rows without a solver are WCSPH's, and the solver is named in
the legend where the files hold more than one)

Left: weak-scaling efficiency (ms per step on 1 GPU with the same particles
per GPU over ms per step on n); right: strong-scaling speed-up (ms per step
on 1 GPU over ms on n), the ideal as a dashed line. Needs matplotlib.
"""
import argparse
import json


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("results", nargs="+")
    ap.add_argument("--png", required=True)
    a = ap.parse_args()
    rows = [r for f in a.results for r in json.load(open(f))]
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (weak, strong) = plt.subplots(1, 2, figsize=(10, 4))
    series = {}
    for r in rows:
        if r["efficiency"] is None:
            continue
        per = r["millions"] / r["gpus"] if r["kind"] == "weak" else r["millions"]
        key = ((r.get("solver") or "wcsph").upper(), r["kind"], per)
        series.setdefault(key, {})[r["gpus"]] = r
    solvers = sorted({s for s, _, _ in series})
    named = len(solvers) > 1
    gpus_all = sorted({r["gpus"] for r in rows})
    for (solver, kind, m), pts in sorted(series.items()):
        g = sorted(pts)
        who = f"{solver} " if named else ""
        style = "os^"[solvers.index(solver) % 3] + "-"  # lines that coincide stay apart
        if kind == "weak":
            weak.plot(g, [100 * pts[k]["efficiency"] for k in g], style, label=f"{who}{m:g}M per GPU")
        else:
            strong.plot(g, [pts[1]["ms_per_step"] / pts[k]["ms_per_step"] for k in g], style, label=f"{who}{m:g}M")
    weak.axhline(85, ls=":", c="gray", label="goal 85%")
    weak.set(xlabel="GPUs", ylabel="weak-scaling efficiency [%]", ylim=(0, 105), xticks=gpus_all,
             title=f"weak scaling (dam break, {', '.join(solvers)})")
    strong.plot(gpus_all, gpus_all, "--", c="gray", label="ideal")
    strong.set(xlabel="GPUs", ylabel="speed-up over 1 GPU", xticks=gpus_all, title="strong scaling")
    weak.legend()
    strong.legend()
    fig.tight_layout()
    fig.savefig(a.png, dpi=110)


if __name__ == "__main__":
    main()
