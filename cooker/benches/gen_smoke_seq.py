"""Writes a generated smoke sequence with real OpenVDB (Debian's python3-openvdb) for the
payload/peer benchmarks: N frames of a rising, swirling plume in a 96^3 box, fog volume `density`,
values in (0, 1] with soft edges and fine noise, inactive where the density is ~0.
Usage: /usr/bin/python3 gen_smoke_seq.py OUT_DIR FRAMES"""

import os
import sys

import numpy as np
import pyopenvdb as vdb

out, frames = sys.argv[1], int(sys.argv[2])
os.makedirs(out, exist_ok=True)
n = 96
x = np.linspace(-1.0, 1.0, n, dtype=np.float32)
gx, gy, gz = np.meshgrid(x, x, x, indexing="ij")
rng = np.random.default_rng(1234)
noise = rng.random((n, n, n), dtype=np.float32)
# Smooth the noise a little (box blur along each axis) so it looks like turbulence.
for axis in range(3):
    noise = (noise + np.roll(noise, 1, axis) + np.roll(noise, -1, axis)) / 3.0
for f in range(frames):
    t = f / max(frames - 1, 1)
    # Plume axis drifts and swirls as it rises.
    cx = 0.25 * np.sin(3.0 * gy + 4.0 * t)
    cz = 0.25 * np.cos(2.5 * gy + 3.0 * t)
    r = np.sqrt((gx - cx) ** 2 + (gz - cz) ** 2)
    width = 0.25 + 0.25 * (gy + 1.0) / 2.0
    height = (gy < -1.0 + 2.0 * (0.3 + 0.7 * t)).astype(np.float32)
    d = np.clip(1.0 - r / width, 0.0, 1.0) ** 1.5 * height
    d *= 0.6 + 0.4 * np.roll(noise, f, axis=1)
    d = np.where(d > 1e-3, d, 0.0).astype(np.float32)
    g = vdb.FloatGrid()
    g.copyFromArray(d, ijk=(0, 0, 0), tolerance=0.0)
    g.name = "density"
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.transform = vdb.createLinearTransform(voxelSize=0.05)
    vdb.write(os.path.join(out, f"smoke.{f + 1:04d}.vdb"), grids=[g])
print(f"wrote {frames} frames to {out}")
