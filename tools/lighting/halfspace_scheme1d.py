#!/usr/bin/env python3
"""The diffusion solve's scheme on the half-space, in 1D: a seconds-long test bench for changes
to the solve's boundary before they are built (issue 34 item 4; docs/rendering.md, "The open face
through the half cell's diffusion problem").

The truth is `halfspace1d.py`'s discrete ordinates (the same half-space: extinction 1, albedo
0.94, isotropic, 24 deep, sun and view straight down). The scheme is the solve's along the
depth: cells of H mean free paths; its source the light scattered twice scattering again
(albedo x the exact second-order fluence, each cell's mean, or with --source centre its value at
the centre, as the gather gives it); faces `(phi_i - phi_j)/R`, `R = r_i + r_j`,
`r = h/2 (3 + |grad phi|/phi)` (Wilson's limiter from the previous iterate); the top face either
the plain vacuum face `r + 2` (--face plain) or the half cell's diffusion problem with the source
exponential in depth from the top two cells (--face halfcell, `vdbcook_scene::ms_vacuum_face`);
solved to convergence. Read as the march reads it, the value at each cell centre, linear between
centres and held from the top centre to the face (--read linear: falling linearly from the
centre to `2J` at the face, Marshak's value, the read tried on 2026-11-27). Prints, per cell width, the radiance seen from
above from the orders the solve carries (third scattering and up) over the truth's, and the top
face's outflow over the truth's.

    python3 tools/lighting/halfspace_scheme1d.py [--face plain|halfcell] [--source mean|centre]
        [--read clamp|linear] [--widths 0.5,1,2,4]

Needs numpy; about 15 s (most of it the truth).
"""
import argparse
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from halfspace1d import orders  # noqa: E402

ALBEDO = 0.94
DEPTH = 24.0


def sinhc(x):
    return 1.0 + x * x / 6.0 if abs(x) < 1e-4 else math.sinh(x) / x


def shape(x, y):
    """F(x, y) = (cosh x - e^-y - y sinhc x) / (x^2 - y^2), nudged off x = |y|."""
    if abs(x * x - y * y) < 1e-8:
        x += 1e-4
    if x < 1e-4 and abs(y) < 1e-4:
        return 0.5 - y / 6.0
    return (math.cosh(x) - math.exp(-y) - y * sinhc(x)) / (x * x - y * y)


def halfcell_face(h, q0, q1, lim_r):
    """The face's resistance and far-side fluence (`vdbcook_scene::ms_vacuum_face`, sigma_r 1)."""
    sa = 1.0 - ALBEDO
    x = 0.5 * h * math.sqrt(3.0 * sa)
    inv_g = 2.0 * math.cosh(x) + 1.5 * h * sinhc(x)
    if q0 <= 0:
        return inv_g + lim_r, 0.0
    y = 0.5 * math.log(q0 / q1) if q1 > 0 else 4.0
    y = max(-4.0, min(4.0, y))
    q_face = q0 * (1.0 + y if abs(y) < 1e-3 else 2.0 * y / -math.expm1(-2.0 * y))
    return inv_g + lim_r, -q_face * 0.75 * h * h * shape(x, y)


def scheme(z, phi2, h, face, source, read, iters=80):
    n = int(round(DEPTH / h))
    c = (np.arange(n) + 0.5) * h
    cell = np.minimum((z / h).astype(int), n - 1)
    if source == "mean":
        q = np.array([ALBEDO * phi2[cell == i].mean() for i in range(n)])
    else:
        q = ALBEDO * np.interp(c, z, phi2)
    sa = 1.0 - ALBEDO
    phi = np.zeros(n)
    top = (0.0, 0.0)
    for it in range(iters):
        lim = np.zeros(n)
        if it:
            grad = np.gradient(np.concatenate([[0.0], phi, [0.0]]), h)[1:-1]
            lim = np.where(phi > 0, np.abs(grad) / np.maximum(phi, 1e-300), 0.0)
        r = 0.5 * h * (3.0 + lim)
        a = np.zeros((n, n))
        b = q * h
        for i in range(n):
            a[i, i] += sa * h
            for j in (i - 1, i + 1):
                if 0 <= j < n:
                    a[i, i] += 1 / (r[i] + r[j])
                    a[i, j] -= 1 / (r[i] + r[j])
                elif j >= n or face == "plain":
                    a[i, i] += 1 / (r[i] + 2.0)
                else:
                    top = halfcell_face(h, q[0], q[1], r[0] - 1.5 * h)
                    a[i, i] += 1 / top[0]
                    b[i] += top[1] / top[0]
        phi = np.linalg.solve(a, b)
    out = phi[0] / (r[0] + 2.0) if face == "plain" else (phi[0] - top[1]) / top[0]
    seen = np.interp(z, c, phi)
    if read == "linear":
        skin = z < c[0]
        seen[skin] = 2 * out + (phi[0] - 2 * out) * z[skin] / c[0]
    return seen, out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--face", choices=["plain", "halfcell"], default="halfcell")
    p.add_argument("--source", choices=["mean", "centre"], default="mean")
    p.add_argument("--read", choices=["clamp", "linear"], default="clamp",
                   help="the top half cell: the centre's value (the march) or linear to 2J")
    p.add_argument("--widths", default="0.375,0.5,1,2,4,8")
    a = p.parse_args()
    z, phis = orders(ALBEDO, 30.0, 0.01, 48, 1e-7)
    keep = z < DEPTH
    z = z[keep]
    phis = [f[keep] for f in phis]
    dz = z[1] - z[0]
    high = np.sum(phis[2:], axis=0)
    seen = lambda f: np.sum(np.exp(-z) * f) * dz  # noqa: E731
    truth = seen(high)
    outflow = np.sum(ALBEDO * phis[1] - (1 - ALBEDO) * high) * dz
    print(f"face {a.face}, source {a.source}, read {a.read}: the solve's orders (third and up)")
    for h in [float(w) for w in a.widths.split(",")]:
        read, out = scheme(z, phis[1], h, a.face, a.source, a.read)
        print(f"  {h:5.3g} mfp a cell: seen from above {seen(read) / truth:.3f}, "
              f"outflow {out / outflow:.3f}")


if __name__ == "__main__":
    main()
