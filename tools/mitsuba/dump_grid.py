#!/usr/bin/python3
"""Dump one float grid of a VDB file to a dense array for render_mitsuba.py.

Runs under the Python that has OpenVDB's bindings (Debian: python3-openvdb, i.e. /usr/bin/python3,
`import pyopenvdb`), which the Mitsuba venv usually lacks.

    /usr/bin/python3 tools/mitsuba/dump_grid.py FILE.vdb GRID OUT_PREFIX

writes OUT_PREFIX.npy (float32, shape [nz, ny, nx]: x fastest in memory, the order Mitsuba's
VolumeGrid expects) and OUT_PREFIX.json:

    {"vdb", "grid", "lo": [i,j,k], "hi": [i,j,k],        first/last voxel of the dense box
     "shape_zyx": [nz,ny,nx], "voxel_scale": [sx,sy,sz], "translate": [tx,ty,tz],
     "background", "active_voxels", "min", "max", "clamped_negative"}

The dense box is the grid's active-voxel bounding box grown by one voxel on every side, so that
its faces hold the background (zero for a fog volume). Voxel ijk's value sits at world position
index_to_world(ijk) = voxel_scale * ijk + translate and covers the index box [ijk - 1/2, ijk + 1/2)
(OpenVDB's nearest sampling). Only transforms that are axis-aligned scale + translate are
accepted; anything with rotation or shear (or a frustum map) is refused.
"""
import json
import sys

import numpy as np
import pyopenvdb as vdb


def axis_aligned(transform):
    """(scale[3], translate[3]) of an axis-aligned index->world map, or raise ValueError."""
    if not transform.isLinear:
        raise ValueError("non-linear (frustum) transform: not supported")
    o = np.array(transform.indexToWorld((0, 0, 0)), dtype=np.float64)
    cols = [np.array(transform.indexToWorld(e), dtype=np.float64) - o
            for e in ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    m = np.stack(cols, axis=1)  # m[:, a] = image of index axis a
    diag = np.diag(m).copy()
    off = m - np.diag(diag)
    tol = 1e-9 * np.abs(diag).max()
    if np.abs(off).max() > tol:
        raise ValueError(f"transform is not axis-aligned (rotation/shear):\n{m}")
    if np.any(diag <= 0):
        raise ValueError(f"transform has a non-positive axis scale: {diag}")
    # Check affinity on an off-axis point too.
    p = np.array(transform.indexToWorld((7, -5, 3)), dtype=np.float64)
    if np.abs(p - (o + m @ np.array([7, -5, 3]))).max() > 1e-6 * (1 + np.abs(p).max()):
        raise ValueError("transform is not affine")
    return diag, o


def dump(path, grid_name, prefix):
    grid = vdb.read(path, grid_name)
    if grid.valueTypeName not in ("float", "double", "half"):
        raise ValueError(f"grid {grid_name!r} has value type {grid.valueTypeName}, need a float grid")
    scale, translate = axis_aligned(grid.transform)
    if grid.activeVoxelCount() == 0:
        raise ValueError("grid has no active voxels")
    bmin, bmax = grid.evalActiveVoxelBoundingBox()
    lo = np.array(bmin, dtype=np.int64) - 1
    hi = np.array(bmax, dtype=np.int64) + 1
    n = hi - lo + 1
    arr = np.zeros(tuple(n), dtype=np.float32)  # [x][y][z], as copyToArray fills it
    grid.copyToArray(arr, ijk=tuple(int(v) for v in lo))
    background = float(grid.background)
    if background != 0.0:
        print(f"warning: background {background} != 0; outside the dense box Mitsuba sees 0",
              file=sys.stderr)
    neg = int(np.count_nonzero(arr < 0))
    if neg:
        print(f"warning: {neg} negative values clamped to 0 (Mitsuba needs sigma_t >= 0)",
              file=sys.stderr)
        arr = np.maximum(arr, 0)
    if not np.all(np.isfinite(arr)):
        raise ValueError("grid has non-finite values")
    zyx = np.ascontiguousarray(arr.transpose(2, 1, 0))  # [z][y][x]: x fastest
    np.save(prefix + ".npy", zyx)
    meta = {
        "vdb": path,
        "grid": grid_name,
        "lo": lo.tolist(),
        "hi": hi.tolist(),
        "shape_zyx": list(zyx.shape),
        "voxel_scale": scale.tolist(),
        "translate": translate.tolist(),
        "background": background,
        "active_voxels": int(grid.activeVoxelCount()),
        "min": float(zyx.min()),
        "max": float(zyx.max()),
        "clamped_negative": neg,
    }
    with open(prefix + ".json", "w") as f:
        json.dump(meta, f, indent=1)
    return meta


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    try:
        m = dump(sys.argv[1], sys.argv[2], sys.argv[3])
    except ValueError as e:
        sys.exit(f"dump_grid: {e}")
    print(json.dumps({k: m[k] for k in ("lo", "hi", "shape_zyx", "voxel_scale", "translate", "max")}))
