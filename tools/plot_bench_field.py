#!/usr/bin/env python3
"""Table and plot for `sphray bench field` results (docs/benchmarks.md).

  plot_bench_field.py docs/bench/bench_field_h100.json --png docs/bench_field.png
      prints the markdown table and writes the error-against-time plot.

Needs python3 with matplotlib (Debian: python3-matplotlib) for the plot.
"""
import argparse
import json


def table(rows):
    out = ["| particles | volume | builder | median ms | speed-up vs best naive | voxels touched | atomics | "
           "skipped | misclassified (band) | differing elsewhere | surface dist. mean / max [voxels] |",
           "|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        best = min(q["median_ms"] for q in rows
                   if q["particles"] == r["particles"] and q["builder"].startswith("naive"))
        out.append("| {:,} | {}^3 | {} | {:.3f} | {:.2f} | {:,} | {:,} | {:,} | {:.3f}% | {} | {:.3f} / {:.3f} |".format(
            r["particles"], r["volume"][0], r["builder"], r["median_ms"], best / r["median_ms"], r["voxels_touched"],
            r["atomics"], r["skipped"], 100 * r["misclassified_share"], r["misclassified_elsewhere"],
            r["surface_distance_mean"], r["surface_distance_max"]))
    return "\n".join(out)


def plot(rows, png, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sizes = sorted({r["particles"] for r in rows})
    builders = ["naive", "naive-thread", "naive-8", "naive-warp", "presence", "presence-thread", "presence-4",
                "presence-8", "presence-warp", "presence-full", "gather"]
    markers = dict(zip(builders, "o<>sD^1234vx"))
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    cmap = plt.get_cmap("viridis")
    for k, n in enumerate(sizes):
        colour = cmap(k / max(1, len(sizes) - 1))
        for r in rows:
            if r["particles"] != n:
                continue
            m = markers.get(r["builder"], "o")
            # Errors of 0 (the naive reference itself) are drawn at the floor of the log axis.
            axes[0].scatter(r["median_ms"], max(100 * r["misclassified_share"], 1e-4), color=colour, marker=m)
            axes[1].scatter(r["median_ms"], max(r["surface_distance_mean"], 1e-4), color=colour, marker=m)
    for ax, label in ((axes[0], "misclassified surface voxels [%] (vs naive)"),
                      (axes[1], "mean distance between iso-surfaces [voxels]")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("median build time [ms]")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    handles = [plt.Line2D([], [], color="k", marker=markers[b], linestyle="", label=b) for b in builders]
    handles += [plt.Line2D([], [], color=cmap(k / max(1, len(sizes) - 1)), marker="o", linestyle="",
                           label="{:,} particles".format(n)) for k, n in enumerate(sizes)]
    axes[1].legend(handles=handles, fontsize=8, loc="upper right")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("json")
    ap.add_argument("--png")
    a = ap.parse_args()
    d = json.load(open(a.json))
    print(table(d["rows"]))
    if a.png:
        plot(d["rows"], a.png, "sphray bench field on {} ({}): error against time".format(d["device"], d["backend"]))


if __name__ == "__main__":
    main()
