#!/usr/bin/python3
"""Write the synthetic fog volumes of the lit mode's per-order checks (docs/rendering.md, "Small
dense effects"): shapes whose light an artist can predict, where each failure shows alone.

    /usr/bin/python3 tools/lighting/make_synthetic.py OUT_DIR

writes, grid `density`, voxel size 1, voxels 0..47 on each axis:

  cube.vdb  density 1 everywhere: flat faces, one lit at a grazing sun under the default light.
  ball.vdb  density 1 inside radius 23 of the centre, 0 outside: a hard, voxelized surface.
  soft.vdb  density 1 − (r/23)², 0 beyond: a smooth edge, as simulated smoke has.
  slab.vdb  density 1 over 96 × 96 × 24 voxels: a half-space seen from straight above (the
            diffusion solve's boundary against the cells' width in mean free paths; docs/
            rendering.md, "A uniform half-space").

Needs Debian's python3-openvdb (`pyopenvdb`). Cook each with `vdbcook cook X.vdb -o X.vdbc
--format f32`.
"""
import os
import sys

import numpy as np
import pyopenvdb as vdb

N = 48


def write(out_dir, name, values):
    grid = vdb.FloatGrid()
    grid.name = "density"
    grid.gridClass = vdb.GridClass.FOG_VOLUME
    grid.copyFromArray(values.astype(np.float32), ijk=(0, 0, 0), tolerance=0)
    vdb.write(os.path.join(out_dir, name + ".vdb"), grids=[grid])


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out_dir = sys.argv[1]
    os.makedirs(out_dir, exist_ok=True)
    centre = np.indices((N, N, N)).astype(np.float64) + 0.5
    r = np.sqrt(((centre - N / 2) ** 2).sum(0))
    radius = N / 2 - 1
    write(out_dir, "cube", np.ones((N, N, N)))
    write(out_dir, "ball", (r < radius).astype(np.float64))
    write(out_dir, "soft", np.clip(1.0 - (r / radius) ** 2, 0.0, None))
    write(out_dir, "slab", np.ones((96, 96, 24)))


if __name__ == "__main__":
    main()
