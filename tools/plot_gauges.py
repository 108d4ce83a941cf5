#!/usr/bin/env python3
"""Plots the gauge columns (NAME_m) of metrics CSVs (sphray run --metrics-csv)
against time, one panel per gauge, one line per file, and prints each
file's RMS and largest difference to the last file (the finest run).

  tools/plot_gauges.py OUT.png LABEL=run1.csv LABEL=run2.csv ...
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read(path):
    rows = list(csv.DictReader(open(path)))
    if not rows:
        sys.exit(f"{path}: no rows")
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out = sys.argv[1]
    runs = []
    for arg in sys.argv[2:]:
        label, _, path = arg.partition("=")
        runs.append((label, read(path)))
    gauges = [k[:-2] for k in runs[0][1] if k.endswith("_m") and k != "front_m"]
    if not gauges:
        sys.exit(f"{sys.argv[2]}: no gauge columns (NAME_m)")
    cols = 2 if len(gauges) > 1 else 1
    rows = (len(gauges) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 3 * rows), sharex=True, squeeze=False)
    for ax, g in zip(axes.flat, gauges):
        for label, d in runs:
            ax.plot(d["time_s"], d[g + "_m"], lw=1, label=label)
        ax.set_title(g)
        ax.set_ylabel("water height [m]")
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(gauges):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    axes.flat[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    ref_label, ref = runs[-1]
    for label, d in runs[:-1]:
        for g in gauges:
            e = d[g + "_m"] - np.interp(d["time_s"], ref["time_s"], ref[g + "_m"])
            print(f"{label} vs {ref_label} {g}: rms {np.sqrt(np.mean(e * e)):.4f} m, max {np.abs(e).max():.3f} m")


if __name__ == "__main__":
    main()
