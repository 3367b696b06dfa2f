#!/usr/bin/python3
"""How many bits a voxel needs under an every-voxel bound, per brick, whatever the format
(issue 33): for each 8³ leaf of a grid whose values span more than 2E (the others are tiles),
with E = FRACTION × the grid's value range:

- `uniform`: ceil(log2(range / 2E + 1)), the bits of a uniform quantizer over the brick's range
  (what the packed formats store, give or take their unorm8 levels);
- `smooth+res 2³` / `3³`: a trilinear base through 2³ or 3³ control points (least squares, one
  byte each) and the residual quantized uniformly: the bits the residual's range needs plus the
  control points' share;
- `palette`: the fewest levels that put every value within E of one (a greedy cover of the
  sorted values, optimal for one dimension), ceil(log2 levels) bits plus one byte per level: the
  best a fixed-rate per-brick scalar quantizer can do;
- `entropy`: the zeroth-order entropy of the uniform quantizer's codes within the brick, the
  floor of a variable-rate (entropy-coded, not randomly addressable) brick.

Means over the bricks, bits per voxel of those bricks. Needs Debian's python3-openvdb (system
python3) and numpy. Usage: tools/gpu_bytes/bits_needed.py FILE.vdb [FRACTION] [GRID]
"""
import math
import sys

import numpy as np
import pyopenvdb as vdb


def trilinear_basis(k):
    xs = np.arange(8) / 7.0 * (k - 1)
    b1 = np.zeros((8, k))
    for i, x in enumerate(xs):
        j = min(int(math.floor(x)), k - 2)
        t = x - j
        b1[i, j] += 1 - t
        b1[i, j + 1] += t
    return np.einsum("ia,jb,kc->ijkabc", b1, b1, b1).reshape(512, k ** 3)


def main():
    path = sys.argv[1]
    frac = float(sys.argv[2]) if len(sys.argv) > 2 else 0.02
    grid = vdb.read(path, sys.argv[3] if len(sys.argv) > 3 else "density")
    lo, hi = grid.evalMinMax()
    e = frac * (hi - lo)
    bases = {k: trilinear_basis(k) for k in (2, 3)}

    def bits(r):
        return 0 if r <= 2 * e else math.ceil(math.log2(r / (2 * e) + 1))

    tot = {"uniform": 0.0, "smooth+res 2³": 0.0, "smooth+res 3³": 0.0, "palette": 0.0,
           "entropy": 0.0}
    n = 0
    bmin, bmax = grid.evalActiveVoxelBoundingBox()
    arr = np.empty((8, 8, 8), dtype=np.float32)
    for x0 in range(bmin[0] // 8 * 8, bmax[0] + 1, 8):
        for y0 in range(bmin[1] // 8 * 8, bmax[1] + 1, 8):
            for z0 in range(bmin[2] // 8 * 8, bmax[2] + 1, 8):
                arr.fill(grid.background)
                grid.copyToArray(arr, ijk=(x0, y0, z0))
                v = arr.reshape(512).astype(np.float64)
                r = v.max() - v.min()
                if r <= 2 * e:
                    continue
                n += 1
                tot["uniform"] += bits(r)
                for k, b in bases.items():
                    c, *_ = np.linalg.lstsq(b, v, rcond=None)
                    res = v - b @ c
                    tot[f"smooth+res {k}³"] += bits(res.max() - res.min()) + k ** 3 * 8 / 512
                s = np.sort(v)
                levels, i = 0, 0
                while i < 512:
                    levels += 1
                    top = s[i] + 2 * e
                    while i < 512 and s[i] <= top:
                        i += 1
                tot["palette"] += math.ceil(math.log2(levels)) + levels * 8 / 512
                q = np.floor((v - v.min()) / (2 * e) + 0.5).astype(np.int64)
                _, cnt = np.unique(q, return_counts=True)
                p = cnt / 512.0
                tot["entropy"] += float(-(p * np.log2(p)).sum())
    print(f"{path}: E = {frac:g} of the range ({e:.4g}), {n} bricks above 2E; bits per voxel: "
          + ", ".join(f"{k} {t / max(n, 1):.2f}" for k, t in tot.items()))


if __name__ == "__main__":
    main()
