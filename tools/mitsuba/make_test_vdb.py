#!/usr/bin/python3
"""Write small synthetic fog VDBs (axis-aligned transforms) for the Mitsuba comparison.

    /usr/bin/python3 tools/mitsuba/make_test_vdb.py OUT_DIR

writes, grid name `density` in each:

  ball.vdb  constant-density (1.0) ball of radius 0.5 centred at (0.3, -0.2, 0.1), voxel size
            0.05, index->world = 0.05 * ijk + (0.3, -0.2, 0.1) (voxel ijk is inside when
            |ijk| <= 10 in index units).
  asym.vdb  an orientation/axis-order probe under a non-uniform scale (0.04, 0.05, 0.06) and
            translation (-0.1, 0.2, 0.05): a ball of density 1 (radius 0.4) at the origin of
            world, a cube of density 3 (side ~0.2) on the +x side, a smaller one of density 6 on
            the +y side, a cube of density 2 on the +z side, and a ramp (density grows along +x)
            across the bottom (-y). Seen from +z with y up, the +x cube is on the right, the +y one
            at the top.
"""
import math
import os
import sys

import numpy as np
import pyopenvdb as vdb


def make_grid(scale, translate):
    g = vdb.FloatGrid()
    g.name = "density"
    g.gridClass = vdb.GridClass.FOG_VOLUME
    m = [[scale[0], 0, 0, 0], [0, scale[1], 0, 0], [0, 0, scale[2], 0],
         [translate[0], translate[1], translate[2], 1]]
    g.transform = vdb.createLinearTransform(m)
    return g


def world_of(scale, translate, lo, shape):
    """World coordinates of every voxel of a dense [x][y][z] block starting at lo."""
    idx = np.indices(shape).astype(np.float64)
    return [idx[a] * 1.0 + lo[a] for a in range(3)], [
        (idx[a] + lo[a]) * scale[a] + translate[a] for a in range(3)]


def ball(out):
    s, t = (0.05, 0.05, 0.05), (0.3, -0.2, 0.1)
    g = make_grid(s, t)
    lo = (-12, -12, -12)
    shape = (25, 25, 25)
    (i, j, k), _ = world_of(s, t, lo, shape)
    arr = np.where(i * i + j * j + k * k <= 100.0, 1.0, 0.0).astype(np.float32)
    g.copyFromArray(arr, ijk=lo, tolerance=0.0)
    vdb.write(os.path.join(out, "ball.vdb"), grids=[g])
    return g


def asym(out):
    s, t = (0.04, 0.05, 0.06), (-0.1, 0.2, 0.05)
    g = make_grid(s, t)
    # World box [-0.7, 0.7]^3 in index space.
    lo = tuple(int(math.floor((-0.75 - t[a]) / s[a])) for a in range(3))
    hi = tuple(int(math.ceil((0.75 - t[a]) / s[a])) for a in range(3))
    shape = tuple(hi[a] - lo[a] + 1 for a in range(3))
    _, (x, y, z) = world_of(s, t, lo, shape)
    arr = np.zeros(shape, dtype=np.float32)
    arr[x * x + y * y + z * z <= 0.4 ** 2] = 1.0
    arr[(np.abs(x - 0.55) < 0.1) & (np.abs(y) < 0.1) & (np.abs(z) < 0.1)] = 3.0
    arr[(np.abs(x) < 0.06) & (np.abs(y - 0.55) < 0.06) & (np.abs(z) < 0.06)] = 6.0
    arr[(np.abs(x) < 0.08) & (np.abs(y) < 0.08) & (np.abs(z - 0.55) < 0.08)] = 2.0
    ramp = (np.abs(x) < 0.6) & (np.abs(y + 0.6) < 0.05) & (np.abs(z) < 0.1)
    arr[ramp] = (2.0 * (x[ramp] + 0.6)).astype(np.float32)
    g.copyFromArray(arr, ijk=lo, tolerance=0.0)
    vdb.write(os.path.join(out, "asym.vdb"), grids=[g])
    return g


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    os.makedirs(sys.argv[1], exist_ok=True)
    for f in (ball, asym):
        g = f(sys.argv[1])
        print(f.__name__, g.activeVoxelCount(), g.evalActiveVoxelBoundingBox())
