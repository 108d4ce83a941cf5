#!/usr/bin/env python3
"""Plots a `sphray bench surface` record: each kernel's surface error against
its build time, refine 0..2 along each line (docs/field.md). The record is
the bench's --json file, or its printed output (the table it ends with; in a
log of several runs, the run after the line "== L=LAYERS", --layers).
    tools/plot_bench_surface.py docs/bench/bench_surface_depths_zhu_bridson_h200.txt docs/field_surface.png --layers 32"""
import argparse
import json
import os
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

# The columns of the bench's printed table (bench/surface.cpp, print_table).
COLUMNS = ["kernel", "refine", "voxel", "build_ms", "pool", "pool_mean", "layer", "layer_mean", "tilt", "ball",
           "ball_mean", "normal", "holes"]


def rows_of_json(j):
    return [{"kernel": r["kernel"], "refine": r["refine"], "build_ms": r["build_ms"],
             "layer": r["pool_from_top_layer"]["rms"], "tilt": r["pool"]["rms_angle_deg"], "ball": r["sphere"]["rms"],
             "particles": r["particles"]["pool"]} for r in j["rows"]], j.get("device", j.get("backend", ""))


def rows_of_text(text, layers):
    if layers is None and len(re.findall(r"^== L=\d+\s*$", text, flags=re.M)) > 1:
        raise SystemExit("the log holds several runs: pick one with --layers")
    if layers is not None:
        blocks = re.split(r"^== L=(\d+)\s*$", text, flags=re.M)
        found = {blocks[k]: blocks[k + 1] for k in range(1, len(blocks) - 1, 2)}
        if str(layers) not in found:
            raise SystemExit(f"no run '== L={layers}' in the log (runs: {', '.join(found) or 'none'})")
        text = found[str(layers)]
    m = re.search(r"pool of (\d+) particles", text)
    rows = []
    for line in text.splitlines():
        f = line.split()
        if len(f) == len(COLUMNS) and f[0] in ("isotropic", "anisotropic", "zhu_bridson") and f[1].isdigit():
            r = dict(zip(COLUMNS, [f[0], int(f[1])] + [float(x) for x in f[2:]]))
            r["particles"] = int(m.group(1)) if m else 0
            rows.append(r)
    if not rows:
        raise SystemExit("no table of sphray bench surface in the log")
    return rows, None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("record")
    ap.add_argument("png")
    ap.add_argument("--layers", type=int, help="in a log of several runs, the run of this depth")
    a = ap.parse_args()
    with open(a.record) as f:
        text = f.read()
    rows, source = rows_of_json(json.loads(text)) if text.lstrip().startswith("{") else rows_of_text(text, a.layers)
    source = source or os.path.basename(a.record) + (f", {a.layers} layers" if a.layers else "")
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    measures = [("layer", "pool height against its top layer, RMS [spacings]"),
                ("tilt", "pool normal tilt, RMS [deg]"),
                ("ball", "ball radius, RMS [spacings]")]
    for ax, (key, label) in zip(axes, measures):
        for kernel, style in (("isotropic", "o-"), ("anisotropic", "s-"), ("zhu_bridson", "^-")):
            kr = sorted((r for r in rows if r["kernel"] == kernel), key=lambda r: r["refine"])
            if not kr:
                continue
            ax.plot([r["build_ms"] for r in kr], [r[key] for r in kr], style, label=kernel)
            for r in kr:
                ax.annotate(f"refine {r['refine']}", (r["build_ms"], r[key]), fontsize=7,
                            textcoords="offset points", xytext=(4, 4))
        ax.set_xlabel("field build [ms], pool of %s particles" % rows[0]["particles"])
        ax.set_ylabel(label)
        ax.set_yscale("symlog", linthresh=0.1)
        ax.grid(True, alpha=0.3)
        ax.legend()
    fig.suptitle("Surface error against build time (sphray bench surface, %s; presence builder, zhu_bridson: gather)"
                 % source)
    fig.tight_layout()
    fig.savefig(a.png, dpi=110)


if __name__ == "__main__":
    main()
