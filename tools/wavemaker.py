#!/usr/bin/env python3
"""Compares the waves of a flap wave-maker scene with linear wave-maker theory.

  tools/wavemaker.py SCENE.json LABEL=metrics.csv [LABEL=metrics.csv ...]

The scene (e.g. scenes/wave_tank.json) has one liquid block filling a flume
along x and one obstacle whose motion turns it about y around a pivot on
the floor (a flap hinged at the bottom); the CSVs are `sphray run
--metrics-csv` runs of it, with a column NAME_m per gauge.

Theory (Biesel & Suquet 1951, as in Dean & Dalrymple, "Water Wave Mechanics
for Engineers and Scientists", 1991): a flap hinged at the
bottom of water of depth h, its stroke S at the still water level (twice
the amplitude of the flap's crossing of that level, 2 h tan(angle)), driven
at period T, makes progressive waves of height

  H / S = 4 (sinh kh / kh) (kh sinh kh - cosh kh + 1) / (sinh 2kh + 2kh),

k from the dispersion relation w^2 = g k tanh kh. Each gauge is compared
while only these waves pass it: from the arrival of the wave train's front
(at the group velocity, from the flap's face) plus one period, until the
wave reflected by the tank's far wall comes back to it; a gauge whose
window is shorter than one period is left out. In the window the measured
height is the largest minus the smallest reading (crest to trough; the
gauges read in quarter spacings), and 2 sqrt(2) times the standard
deviation over one period (the height of a sinusoid of that spread).
"""
import csv
import json
import math
import sys


def fail(message):
    print(f"wavemaker.py: {message}", file=sys.stderr)
    sys.exit(2)


def wavenumber(omega, depth, g):
    """k of w^2 = g k tanh(k h): kh by bisection (kh tanh kh grows with kh)."""
    target = omega * omega * depth / g
    lo, hi = 0.0, max(target, math.sqrt(target)) + 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid * math.tanh(mid) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi) / depth


def flap_height_over_stroke(kh):
    """H / S of a bottom-hinged flap (linear theory; kh / 2 in shallow water, 2 in deep)."""
    return 4.0 * (math.sinh(kh) / kh) * (kh * math.sinh(kh) - math.cosh(kh) + 1.0) / (math.sinh(2 * kh) + 2 * kh)


def flume(scene):
    """The flume's depth, the flap's period, stroke and face, the far wall, the gauges."""
    if len(scene.get("fluid", [])) != 1 or len(scene.get("obstacles", [])) != 1:
        fail("the scene needs one fluid block and one obstacle (the flap)")
    fluid, flap = scene["fluid"][0], scene["obstacles"][0]
    motion = flap.get("motion")
    if not motion or "rotate" not in motion or "pivot" not in motion:
        fail("the obstacle needs a motion with rotate and pivot (a flap)")
    rotate = motion["rotate"]
    if rotate[0] != 0 or rotate[2] != 0 or rotate[1] == 0:
        fail("the flap must turn about y only")
    floor = scene["tank"]["min"][2]
    depth = fluid["max"][2] - floor
    if abs(motion["pivot"][2] - floor) > 0.05 * depth:
        fail("the flap's pivot must lie on the floor (the theory is that of a bottom-hinged flap)")
    scale = flap.get("scale", [1, 1, 1])
    scale = scale if isinstance(scale, list) else [scale] * 3
    face = flap.get("translate", [0, 0, 0])[0] + scale[0]  # unit_box spans [0, 1]: the face toward +x
    gauges = scene.get("gauges", [])
    if not gauges:
        fail("the scene has no gauges")
    g = math.sqrt(sum(c * c for c in scene.get("gravity", [0, 0, -9.81])))
    return {
        "depth": depth,
        "period": motion["period"],
        "stroke": 2 * depth * math.tan(math.radians(abs(rotate[1]))),
        "face": face,
        "far_wall": scene["tank"]["max"][0],
        "gauges": [(gauge["name"], gauge["at"][0]) for gauge in gauges],
        "g": g,
    }


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    try:
        scene = json.load(open(sys.argv[1]))
    except (OSError, ValueError) as e:
        fail(f"{sys.argv[1]}: {e}")
    f = flume(scene)
    T, h = f["period"], f["depth"]
    omega = 2 * math.pi / T
    k = wavenumber(omega, h, f["g"])
    kh = k * h
    length = 2 * math.pi / k
    c = length / T
    cg = 0.5 * c * (1 + 2 * kh / math.sinh(2 * kh))
    H = flap_height_over_stroke(kh) * f["stroke"]
    print(f"depth {h:.4f} m, period {T} s, stroke {f['stroke']:.4f} m: kh {kh:.3f}, wave length {length:.3f} m, "
          f"phase speed {c:.3f} m/s, group speed {cg:.3f} m/s, H/S {H / f['stroke']:.3f}, "
          f"H {H * 1000:.1f} mm (H/L {H / length:.4f}, H/h {H / h:.3f})")
    windows = {}
    for name, x in f["gauges"]:
        t0 = (x - f["face"]) / cg + T
        t1 = (2 * f["far_wall"] - f["face"] - x) / cg
        if t1 - t0 >= T:
            windows[name] = (t0, t1)
        else:
            print(f"{name} (x = {x} m): the reflected wave returns {t1:.2f} s, within a period of the "
                  f"wave train's arrival: left out")
    table = []  # printed once every run is read: a bad file leaves no partial table
    for arg in sys.argv[2:]:
        label, _, path = arg.partition("=")
        try:
            rows = list(csv.DictReader(open(path)))
        except OSError as e:
            fail(f"{path}: {e}")
        for name, (t0, t1) in windows.items():
            column = name + "_m"
            if not rows or column not in rows[0]:
                fail(f"{path}: no column {column}")
            window = [(float(r["time_s"]), float(r[column])) for r in rows if t0 <= float(r["time_s"]) <= t1]
            period = [y for t, y in window if t <= t0 + T]
            if not window or window[-1][0] < t1 - 0.05 * T:
                fail(f"{path}: the run ends before {t1:.2f} s")
            crest_trough = max(y for _, y in window) - min(y for _, y in window)
            mean = sum(period) / len(period)
            spread = 2 * math.sqrt(2) * math.sqrt(sum((y - mean) ** 2 for y in period) / len(period))
            table.append(f"| {label} | {name} | {t0:.2f}-{t1:.2f} | {crest_trough * 1000:.1f} ({crest_trough / H - 1:+.0%}) "
                         f"| {spread * 1000:.1f} ({spread / H - 1:+.0%}) | {H * 1000:.1f} |")
    print("| run | gauge | window [s] | crest to trough [mm] | 2 sqrt(2) std over a period [mm] | theory [mm] |")
    print("| --- | --- | --- | ---: | ---: | ---: |")
    print("\n".join(table))


if __name__ == "__main__":
    main()
