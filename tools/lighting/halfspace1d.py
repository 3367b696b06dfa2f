#!/usr/bin/env python3
"""A uniform half-space lit straight from above, solved by orders of scattering with discrete
ordinates: the independent truth for the solve's boundary (issue 34 item 4,
docs/rendering.md "A uniform half-space").

Medium: extinction 1 per unit length (one mean free path), albedo A, isotropic phase, DEPTH deep;
sun of irradiance 1 at normal incidence. Each order's fluence phi_n(z) comes from the previous
order's isotropic emission A*phi_{n-1}/(4 pi) swept along NMU Gauss-Legendre directions, each cell
of DZ integrated exactly for a constant source. Prints the radiance seen from straight above by
order (its shares: single, second, third, fourth and up, as the path tracer's `--bounces 1, 2, 3`
references split them) and the scattered light absorbed, (1 - A) * integral of sum phi_n dz.

    python3 tools/lighting/halfspace1d.py [--albedo 0.94] [--depth 24] [--dz 0.01]

At albedo 0.94 and 24 deep the shares are 0.245 / 0.160 / 0.113 / 0.482 (the path tracer's
references of `slab.vdb` at 4096 spp: the same to three digits) and the absorbed scattered light
0.06 * 7.247 (`vdbcook_trace::diffusion`'s `a_thick_slab_absorbs_alike_at_any_cell_width`).
Needs numpy; about 10 s.
"""
import argparse
import numpy as np


def orders(albedo, depth, dz, nmu, tol):
    z = (np.arange(int(round(depth / dz))) + 0.5) * dz
    mus, weights = np.polynomial.legendre.leggauss(nmu)
    emit = albedo * np.exp(-z) / (4 * np.pi)  # the sun's beam scattered once, per sr
    out = []
    while True:
        phi = np.zeros_like(z)
        for mu, w in zip(mus, weights):
            t = np.exp(-dz / abs(mu))
            rad = np.zeros_like(z)
            run = 0.0
            cells = range(len(z)) if mu > 0 else range(len(z) - 1, -1, -1)
            for i in cells:
                before = run
                run = before * t + emit[i] * (1 - t)
                rad[i] = 0.5 * (before + run)
            phi += 2 * np.pi * w * rad
        out.append(phi)
        if phi.max() < tol:
            return z, out
        emit = albedo * phi / (4 * np.pi)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--albedo", type=float, default=0.94)
    p.add_argument("--depth", type=float, default=24.0)
    p.add_argument("--dz", type=float, default=0.01)
    p.add_argument("--nmu", type=int, default=48)
    a = p.parse_args()
    if not (0 < a.albedo <= 1 and a.depth > 0 and 0 < a.dz < a.depth and a.nmu > 1):
        p.error("need 0 < albedo <= 1, depth > 0, 0 < dz < depth, nmu > 1")
    z, phis = orders(a.albedo, a.depth, a.dz, a.nmu, 1e-7)
    dz = a.dz
    k = a.albedo / (4 * np.pi)
    radiance = [k * np.sum(np.exp(-2 * z)) * dz]
    radiance += [k * np.sum(np.exp(-z) * p) * dz for p in phis]
    total = sum(radiance)
    shares = radiance[:3] + [sum(radiance[3:])]
    print(f"orders {len(phis) + 1}, radiance from above {total:.6f} per unit irradiance")
    print("shares 1st / 2nd / 3rd / 4th+: " + " / ".join(f"{s / total:.4f}" for s in shares))
    fl = np.sum(phis, axis=0).sum() * dz
    print(f"integral of the scattered fluence {fl:.4f}; absorbed {(1 - a.albedo) * fl:.4f}")


if __name__ == "__main__":
    main()
