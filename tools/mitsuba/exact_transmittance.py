#!/usr/bin/env python3
"""Exact transmittance T = exp(-extinction * integral of density) through the pixel centres of a
scene (render_mitsuba.py's JSON), by walking every voxel plane in float64: a noise-free
reference for both vdbcook's density mode (which writes 1 - T) and Mitsuba's albedo-0 render
(which estimates T). Same voxel convention and camera contract as render_mitsuba.py.

    /tmp/mi-venv/bin/python tools/mitsuba/exact_transmittance.py SCENE.json -o T.pfm [--one-minus]
"""
import argparse
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from pfm import write_pfm  # noqa: E402
from render_mitsuba import camera_basis, load_grid, normalize  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--one-minus", action="store_true", help="write 1 - T (vdbcook's density image)")
    ap.add_argument("--cache", default="/tmp/vdbcook-mitsuba-cache")
    args = ap.parse_args()
    with open(args.scene) as f:
        sc = json.load(f)
    base = os.path.dirname(os.path.abspath(args.scene))
    vdb_path = sc["vdb"] if os.path.isabs(sc["vdb"]) else os.path.join(base, sc["vdb"])
    data, meta = load_grid(vdb_path, sc["grid"], args.cache)
    vals = data.transpose(2, 1, 0).astype(np.float64)  # [x][y][z]
    n = np.array(vals.shape)
    lo = np.array(meta["lo"], dtype=np.float64)
    s = np.array(meta["voxel_scale"], dtype=np.float64)
    t = np.array(meta["translate"], dtype=np.float64)

    eye, fw, r, u, th, W, H = camera_basis(sc)
    # Cell space of the dense block: dense voxel v covers [v, v + 1); c = (w - t)/s - (lo - 1/2).
    oc = (eye - t) / s - (lo - 0.5)
    tau = np.zeros((H, W))
    for j in range(H):
        for i in range(W):
            d = normalize(fw + (2 * (i + 0.5) / W - 1) * th * (W / H) * r + (1 - 2 * (j + 0.5) / H) * th * u)
            dc = d / s  # cell units per world unit of t
            with np.errstate(divide="ignore", invalid="ignore"):
                ta = np.where(dc != 0, (0 - oc) / dc, -np.inf)
                tb = np.where(dc != 0, (n - oc) / dc, np.inf)
            inside0 = np.all((dc != 0) | ((oc >= 0) & (oc <= n)))
            if not inside0:
                continue
            t0 = max(np.max(np.minimum(ta, tb)), 0.0)
            t1 = np.min(np.maximum(ta, tb))
            if not t1 > t0:
                continue
            ts = [np.array([t0, t1])]
            for a in range(3):
                if dc[a] == 0:
                    continue
                ca, cb = sorted((oc[a] + t0 * dc[a], oc[a] + t1 * dc[a]))
                k = np.arange(math.ceil(ca), math.floor(cb) + 1, dtype=np.float64)
                ts.append((k - oc[a]) / dc[a])
            tt = np.unique(np.clip(np.concatenate(ts), t0, t1))
            mid = (tt[:-1] + tt[1:]) / 2
            c = oc[None, :] + mid[:, None] * dc[None, :]
            v = np.clip(np.floor(c).astype(np.int64), 0, n - 1)
            sig = np.maximum(vals[v[:, 0], v[:, 1], v[:, 2]], 0.0)
            tau[j, i] = float(np.sum(sig * np.diff(tt)))
    T = np.exp(-float(sc["extinction"]) * tau)
    img = 1.0 - T if args.one_minus else T
    write_pfm(args.output, np.repeat(img[:, :, None], 3, axis=2))
    print(json.dumps({"output": args.output, "mean_T": float(T.mean()), "min_T": float(T.min())}))


if __name__ == "__main__":
    main()
