#!/usr/bin/env python3
"""Martin & Moyce (1952) dam-break validation: error against run time.

  validate.py run --sphray BUILD/sphray --backend cpu --resolutions 10,20 --out results.json
      runs scenes/validation/martin_moyce.json at spacing a/N for each N, and
      records the surge-front error against the experiment and the wall time.
  validate.py report results_cpu.json results_cuda.json ... [--png docs/validation_front.png]
      prints the table for docs/validation.md and writes the plot (surge fronts; error against wall time).
  --set KEY=VALUE (run, repeatable) is passed on to every sphray run, e.g. --set sph.smoothing_ratio=1.5;
      the results record it and the report labels them with it.

Needs python3 with matplotlib (Debian: python3-matplotlib) for `report` only.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "scenes/validation/martin_moyce.json")
DATA = os.path.join(ROOT, "data/martin_moyce_1952.csv")
A = 0.05715  # column width [m], 2.25 in
G = 9.81


def experiment():
    rows = [l.strip().split(",") for l in open(DATA) if l[:1].isdigit()]
    return [float(r[0]) for r in rows], [float(r[1]) for r in rows]


def interp(xs, ys, x):
    if x <= xs[0]:
        return ys[0]
    for k in range(1, len(xs)):
        if x <= xs[k]:
            t = (x - xs[k - 1]) / (xs[k] - xs[k - 1])
            return ys[k - 1] + t * (ys[k] - ys[k - 1])
    return ys[-1]


def front_error(T, Z):
    te, ze = experiment()
    rel = [(interp(T, Z, t) - z) / z for t, z in zip(te, ze) if t <= T[-1] + 1e-12]
    return math.sqrt(sum(r * r for r in rel) / len(rel)), max(abs(r) for r in rel), len(rel)


def run(args):
    results = []
    for n in [int(x) for x in args.resolutions.split(",")]:
        spacing = A / n
        with tempfile.TemporaryDirectory() as tmp:
            metrics, summary = os.path.join(tmp, "m.csv"), os.path.join(tmp, "s.json")
            cmd = [args.sphray, "run", SCENE, "--backend", args.backend, "--quiet",
                   "--set", f"sph.spacing={spacing:.9g}", "--metrics-csv", metrics, "--summary-json", summary]
            for o in args.set:
                cmd += ["--set", o]
            print("running:", " ".join(cmd), flush=True)
            try:
                subprocess.run(cmd, check=True, timeout=args.timeout)
            except subprocess.TimeoutExpired:
                print(f"  a/{n}: stopped after {args.timeout} s, not recorded", flush=True)
                continue
            except subprocess.CalledProcessError as e:  # sphray has said why (a bad --set, say)
                sys.exit(f"validate.py: a/{n}: sphray exited with code {e.returncode}; nothing written to {args.out}")
            rows = list(csv.DictReader(open(metrics)))
            s = json.load(open(summary))
        T = [float(r["time_s"]) * math.sqrt(2 * G / A) for r in rows]
        Z = [float(r["front_m"]) / A for r in rows]
        rms, worst, points = front_error(T, Z)
        results.append({"backend": args.backend, "a_over_dx": n, "spacing_m": spacing,
                        "particles": s["fluid_start"], "steps": s["steps"], "wall_s": s["wall_s"],
                        "rms_relative_error": rms, "max_relative_error": worst, "points": points,
                        "wall_clamps": s["clamped"], "overrides": args.set, "T": T, "Z": Z,
                        "command": " ".join(cmd)})
        print(f"  a/{n}: {s['fluid_start']} particles, {s['steps']} steps, {s['wall_s']:.1f} s, "
              f"RMS {100 * rms:.1f}% (max {100 * worst:.1f}%)", flush=True)
    with open(args.out, "w") as f:
        json.dump({"device": args.device, "results": results}, f, indent=1)


def tag(r):
    """The run's --set overrides, for a label (empty for the scene as it is)."""
    o = r.get("overrides", [])
    return f" [{', '.join(x.replace('sph.smoothing_ratio=', 'h/dx=') for x in o)}]" if o else ""


def report(args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sets = [json.load(open(p)) for p in args.files]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    te, ze = experiment()
    ax1.plot(te, ze, "ko", label="Martin & Moyce 1952")
    for s in sets:
        for r in s["results"]:
            ax1.plot(r["T"], r["Z"], "-", lw=1, label=f"{r['backend']} a/{r['a_over_dx']}{tag(r)}")
    ax1.set_xlabel("T = t sqrt(2g/a)")
    ax1.set_ylabel("Z = front / a")
    ax1.set_xlim(0, 10)
    ax1.set_ylim(0, 16)
    ax1.legend(fontsize=7)
    ax1.set_title("Surge front")
    for s in sets:
        rs = s["results"]
        if not rs:
            continue
        ax2.semilogx([r["wall_s"] for r in rs], [100 * r["rms_relative_error"] for r in rs], "o-",
                   label=f"{rs[0]['backend']} ({s['device']}){tag(rs[0])}")
        for r in rs:
            ax2.annotate(f"a/{r['a_over_dx']}", (r["wall_s"], 100 * r["rms_relative_error"]), fontsize=7)
    ax2.set_xlabel("wall time [s]")
    ax2.set_ylabel("RMS relative front error [%]")
    ax2.set_title("Error against run time")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    png = args.png
    fig.savefig(png, dpi=110)

    # A settings column only where some run had --set overrides.
    with_settings = any(r.get("overrides") for s in sets for r in s["results"])
    head = ["backend", "device"] + (["settings"] if with_settings else []) + [
        "a/dx", "fluid particles", "steps", "wall time [s]", "RMS rel. error", "max rel. error", "wall clamps"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for s in sets:
        for r in s["results"]:
            cells = [r["backend"], s["device"]] + ([", ".join(r.get("overrides", [])) or "scene"] if with_settings else []) + [
                str(r["a_over_dx"]), str(r["particles"]), str(r["steps"]), f"{r['wall_s']:.1f}",
                f"{100 * r['rms_relative_error']:.1f}%", f"{100 * r['max_relative_error']:.1f}%", str(r["wall_clamps"])]
            lines.append("| " + " | ".join(cells) + " |")
    print("\n".join(lines))
    print("wrote", png, "; the table above goes into docs/validation.md")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--sphray", required=True)
    r.add_argument("--backend", default="cpu")
    r.add_argument("--resolutions", default="10,20")
    r.add_argument("--device", default="cpu")
    r.add_argument("--timeout", type=float, default=3000)
    r.add_argument("--out", required=True)
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="passed on to every run (sphray run --set), e.g. sph.smoothing_ratio=1.5")
    q = sub.add_parser("report")
    q.add_argument("files", nargs="+")
    q.add_argument("--png", default=os.path.join(ROOT, "docs/validation_front.png"), help="where the plot goes")
    args = p.parse_args()
    run(args) if args.cmd == "run" else report(args)


if __name__ == "__main__":
    sys.exit(main())
