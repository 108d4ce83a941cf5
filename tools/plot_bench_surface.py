#!/usr/bin/env python3
"""Plots a `sphray bench surface --json` record: each kernel's surface error
against its build time, refine 0..2 along each line (docs/field.md).
    tools/plot_bench_surface.py docs/bench/bench_surface_h100.json docs/field_surface.png"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def main(src, dst):
    with open(src) as f:
        j = json.load(f)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    measures = [("pool", "rms", "pool height, RMS [spacings]"),
                ("pool", "rms_angle_deg", "pool normal tilt, RMS [deg]"),
                ("sphere", "rms", "ball radius, RMS [spacings]")]
    for ax, (shape, key, label) in zip(axes, measures):
        for kernel, style in (("isotropic", "o-"), ("anisotropic", "s-"), ("zhu_bridson", "^-")):
            rows = sorted((r for r in j["rows"] if r["kernel"] == kernel), key=lambda r: r["refine"])
            if not rows:
                continue
            ax.plot([r["build_ms"] for r in rows], [r[shape][key] for r in rows], style, label=kernel)
            for r in rows:
                ax.annotate(f"refine {r['refine']}", (r["build_ms"], r[shape][key]), fontsize=7,
                            textcoords="offset points", xytext=(4, 4))
        ax.set_xlabel("field build [ms], pool of %s particles" % j["rows"][0]["particles"]["pool"])
        ax.set_ylabel(label)
        ax.set_yscale("symlog", linthresh=0.1)
        ax.grid(True, alpha=0.3)
        ax.legend()
    fig.suptitle("Surface error against build time, %s (sphray bench surface; presence builder, zhu_bridson: gather)"
                 % j.get("device", j.get("backend", "")))
    fig.tight_layout()
    fig.savefig(dst, dpi=110)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
