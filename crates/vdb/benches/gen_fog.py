"""Writes the reader benchmark's input with real OpenVDB (Debian's python3-openvdb):
a dense N^3 fog grid named `density` with smooth non-constant values, saved with OpenVDB's
default compression (blosc + active mask). Usage: /usr/bin/python3 gen_fog.py OUT.vdb N"""

import sys

import numpy as np
import pyopenvdb as vdb

out, n = sys.argv[1], int(sys.argv[2])
x = np.linspace(0.0, 1.0, n, dtype=np.float32)
gx, gy, gz = np.meshgrid(x, x, x, indexing="ij")
# Smooth density in (0.05, 1]: a soft ball plus ripples, never equal to the background 0.
vals = 0.55 + 0.4 * np.sin(6.0 * gx) * np.cos(5.0 * gy) * np.sin(4.0 * gz + 1.0)
vals = np.clip(vals, 0.05, 1.0).astype(np.float32)
grid = vdb.FloatGrid()
grid.copyFromArray(vals, ijk=(0, 0, 0), tolerance=0.0)
grid.name = "density"
grid.gridClass = vdb.GridClass.FOG_VOLUME
vdb.write(out, grids=[grid])
print(f"wrote {out}: {grid.activeVoxelCount()} active voxels")
