"""Writes a large generated cloud sequence with real OpenVDB (Debian's python3-openvdb) for the
clustering report: FRAMES frames of a dense N^3 cloud (default 144^3: 18^3 = 5832 leaves per
frame, so 100 frames give 583,200 source bricks), fog volume `density`. The interior is smooth
(low variance: what clustering should merge), the edges and a drifting turbulent band carry
fine detail (high variance: what it must leave alone).
Usage: /usr/bin/python3 gen_cloud_seq.py OUT_DIR FRAMES [N]"""

import os
import sys

import numpy as np
import pyopenvdb as vdb

out, frames = sys.argv[1], int(sys.argv[2])
n = int(sys.argv[3]) if len(sys.argv) > 3 else 144
os.makedirs(out, exist_ok=True)
x = np.linspace(-1.0, 1.0, n, dtype=np.float32)
gx, gy, gz = np.meshgrid(x, x, x, indexing="ij")
rng = np.random.default_rng(99)
base = rng.random((n, n, n), dtype=np.float32)
for axis in range(3):
    base = (base + np.roll(base, 1, axis) + np.roll(base, -1, axis)) / 3.0
r = np.sqrt(gx**2 + (0.8 * gy) ** 2 + gz**2)
for f in range(frames):
    t = f / max(frames - 1, 1)
    body = np.clip(1.2 - r, 0.05, 1.0)
    band = np.exp(-(((gy - (-0.8 + 1.6 * t)) / 0.15) ** 2))
    detail = np.roll(base, 3 * f, axis=0) - 0.5
    d = body * (0.6 + 0.02 * np.sin(4.0 * gx + 2.0 * t)) + 0.5 * band * detail
    d = np.clip(d, 0.01, 2.0).astype(np.float32)
    g = vdb.FloatGrid()
    g.copyFromArray(d, ijk=(0, 0, 0), tolerance=0.0)
    g.name = "density"
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.transform = vdb.createLinearTransform(voxelSize=0.02)
    vdb.write(os.path.join(out, f"cloud.{f + 1:04d}.vdb"), grids=[g])
print(f"wrote {frames} frames of {n}^3 to {out}")
