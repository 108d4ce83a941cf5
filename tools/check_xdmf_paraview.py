#!/usr/bin/env pvpython
"""Opens an export's XDMF sidecar with ParaView's Xdmf3 reader and checks it
against the HDF5 file read with h5py: every time step, the walls, the particles
with each exported dataset as a point array of the right size and range, and
the density field contoured at its iso enclosing the particles.

    pvpython tools/check_xdmf_paraview.py out.xmf     (Debian: paraview python3-paraview python3-h5py)

Prints one line per time step and "ok", or what differs (exit 1)."""
import sys

import h5py
import numpy as np
from paraview import servermanager as sm
from paraview.simple import Contour, Xdmf3ReaderT
from vtkmodules.numpy_interface import dataset_adapter as dsa

xmf = sys.argv[1]
h5 = h5py.File(xmf[: -len(".xmf")] + ".h5", "r")
frames = sorted(h5["frames"])
reader = Xdmf3ReaderT(FileName=[xmf])
reader.UpdatePipelineInformation()
times = list(reader.TimestepValues)
bad = []


def expect(cond, what):
    if not cond:
        bad.append(what)


expect(np.allclose(times, [h5["frames"][n].attrs["time"] for n in frames]), f"time steps {times}")
for name, t in zip(frames, times):
    g = h5["frames"][name]
    reader.UpdatePipeline(t)
    # the sidecar's top-level grids, in its order: walls, particles, field
    top = sm.Fetch(reader)
    names = ["walls", "particles", "field"][: top.GetNumberOfBlocks()]
    blocks = {n: top.GetBlock(k) for k, n in enumerate(names)}
    walls = blocks.get("walls")
    expect(walls is not None and walls.GetNumberOfPoints() == len(h5["boundary/position"]), f"{name}: walls")
    parts = dsa.WrapDataObject(blocks["particles"])
    n = len(g["position"])
    expect(parts.GetNumberOfPoints() == n, f"{name}: {parts.GetNumberOfPoints()} particles, the file {n}")
    if n:
        expect(np.array_equal(parts.Points, g["position"][...]), f"{name}: positions")
    for ds in ("id", "velocity", "density", "pressure", "presence"):
        if ds in g and n:
            arr = parts.PointData[ds]
            expect(arr is not None and np.array_equal(np.asarray(arr).reshape(g[ds].shape), g[ds][...]),
                   f"{name}: point array {ds}")
    line = f"{name} t = {t:.4f} s: {parts.GetNumberOfPoints()} particles, arrays {list(parts.PointData.keys())}"
    if "field" in g:
        f = g["field"]
        grid = blocks["field"]
        v = float(f.attrs["voxel_size"])
        o = f.attrs["origin"] + 0.5 * v
        b = grid.GetBounds()
        expect(np.allclose([b[0], b[2], b[4]], o, atol=1e-5) and grid.GetDimensions() == f.shape[::-1],
               f"{name}: field grid {b} {grid.GetDimensions()}")
        # the iso-surface encloses the particles, within a voxel or two
        c = Contour(Input=reader, ContourBy=["POINTS", "field"], Isosurfaces=[float(f.attrs["iso"])])
        c.UpdatePipeline(t)
        cb = c.GetDataInformation().GetBounds()
        line += f"; field {grid.GetDimensions()}"
        if n:
            pb = parts.GetBounds()
            expect(all(abs(cb[k] - pb[k]) < 2.5 * v for k in range(6)), f"{name}: iso-surface {cb} vs particles {pb}")
            line += f", iso-surface x {cb[0]:.3f} .. {cb[1]:.3f} m (particles {pb[0]:.3f} .. {pb[1]:.3f})"
        else:
            expect(c.GetDataInformation().GetNumberOfPoints() == 0, f"{name}: an iso-surface without particles")
    print(line)
for b in bad:
    print("MISMATCH", b)
print("ok" if not bad else f"{len(bad)} mismatches")
sys.exit(1 if bad else 0)
