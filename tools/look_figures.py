#!/usr/bin/env python3
"""Assemble docs/rendering.md's look figures from the frames of `tools/gpu-check.sh look`.

    tools/look_figures.py DIR [OUTDIR]

DIR holds the 1920x1080 frames that step writes, look_<film>_<particles>.png
with film clear, defaults, ellipsoids and particles 125000, 1000000, and
close_<film>.png with film spheres_clear, ellipsoids. OUTDIR (default
docs/img) receives:

  look_1M.png        the 1M frames halved to 960x540, cropped to 660x300 at
                     (150, 125), stacked: clear film, defaults, ellipsoids
  look_125k.png      the 125k frames to a third (640x360), cropped to 474x300
                     at (83, 0), side by side in the same order
  look_1M_close.png  the close-ups halved, stacked: spheres with a clear film
                     above, the defaults with ellipsoids below

A figure whose frames are not all in DIR is skipped and named.
"""
import os
import sys

from PIL import Image

FILMS = ("clear", "defaults", "ellipsoids")


def scaled(path, factor):
    im = Image.open(path).convert("RGBA")
    if im.size != (1920, 1080):
        raise SystemExit(f"{path}: {im.size[0]}x{im.size[1]}, expected the 1920x1080 of bench frame")
    return im.resize((1920 // factor, 1080 // factor), Image.LANCZOS)


def crop(im, w, h, x, y):
    return im.crop((x, y, x + w, y + h))


def assemble(paths, place, size, out):
    missing = [p for p in paths if not os.path.isfile(p)]
    if missing:
        print(f"{out}: skipped, missing {', '.join(missing)}")
        return
    sheet = Image.new("RGBA", size)
    for i, p in enumerate(paths):
        im = place(p)
        sheet.paste(im, (0, i * im.size[1]) if size[0] == im.size[0] else (i * im.size[0], 0))
    sheet.save(out, optimize=True)
    print(f"{out}: {size[0]}x{size[1]} from {', '.join(os.path.basename(p) for p in paths)}")


def main():
    if len(sys.argv) not in (2, 3):
        raise SystemExit(__doc__)
    src = sys.argv[1]
    dst = sys.argv[2] if len(sys.argv) == 3 else os.path.join(os.path.dirname(__file__), "..", "docs", "img")
    if not os.path.isdir(src):
        raise SystemExit(f"{src}: not a directory")
    os.makedirs(dst, exist_ok=True)
    frames = lambda n: [os.path.join(src, f"look_{f}_{n}.png") for f in FILMS]
    assemble(frames(1000000), lambda p: crop(scaled(p, 2), 660, 300, 150, 125), (660, 900),
             os.path.join(dst, "look_1M.png"))
    assemble(frames(125000), lambda p: crop(scaled(p, 3), 474, 300, 83, 0), (1422, 300),
             os.path.join(dst, "look_125k.png"))
    assemble([os.path.join(src, f"close_{f}.png") for f in ("spheres_clear", "ellipsoids")],
             lambda p: scaled(p, 2), (960, 1080), os.path.join(dst, "look_1M_close.png"))


if __name__ == "__main__":
    main()
