#!/usr/bin/env python3
"""Compare two linear PFMs (A = vdbcook, B = Mitsuba, usually).

    python3 tools/mitsuba/compare.py A.pfm B.pfm [--one-minus-a] [--downsample-a K]
        [--mask-from X.pfm] [--threshold 1e-3] [--stderr-b ERR.pfm] [--diff D.pfm] [--a2 A2.pfm]
        [--b2 B2.pfm [--b2-spp-ratio R]]

--one-minus-a   compare 1 - A with B (vdbcook's density mode writes 1 - T; Mitsuba with albedo 0,
                sky 1 and hide_emitters false renders T).
--downsample-a K  A was rendered at K times B's width and height: box-average K x K blocks
                (vdbcook traces one ray through each pixel centre; Mitsuba's sensor averages over
                the pixel's area, so a K-times supersampled vdbcook image is the fair match).
--mask-from X   judge only pixels where X (mean over channels; downsampled like A when it has A's
                size) exceeds --threshold. Default: pixels where A or B (before --one-minus-a)
                exceeds it.
--stderr-b E    per-pixel standard error of B (render_mitsuba.py --stderr-out): reports the
                RMSE that B's noise alone would give, relative like the RMSE
                (noise_rel_rmse_b).
--b2 B2         an independent render of B (another seed), for a B without --stderr-b (vdbcook's
                `--mode reference`): B's noise is estimated from B - B2, whose variance is B's
                times (1 + R), R = --b2-spp-ratio (B's samples per pixel over B2's; default 1), so
                a cheaper B2 serves (R = 8: a 1024-spp B2 for an 8192-spp B). B stays B.

Prints one JSON object: pixels judged, rel_rmse = sqrt(mean((a-b)^2)) / mean(b), max_abs,
mean_a, mean_b, mean_ratio = mean_a / mean_b (all over the judged pixels and the 3 channels),
per-channel mean ratios; with --stderr-b, --b2 and/or --a2 (a second render of A with another
seed: A is taken as the mean of the two, and half their difference estimates its noise) the
noise-only rel RMSE of each side and excess_rel_rmse = sqrt(RMSE^2 - noise_a^2 - noise_b^2) /
mean(b), the part of the difference that noise does not explain.
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pfm import read_pfm, write_pfm  # noqa: E402


def downsample(img, k):
    h, w, c = img.shape
    if h % k or w % k:
        sys.exit(f"cannot downsample {w}x{h} by {k}")
    return img.reshape(h // k, k, w // k, k, c).mean(axis=(1, 3))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--one-minus-a", action="store_true")
    ap.add_argument("--downsample-a", type=int, default=1)
    ap.add_argument("--mask-from")
    ap.add_argument("--threshold", type=float, default=1e-3)
    ap.add_argument("--stderr-b")
    ap.add_argument("--a2", help="a second render of A with another seed: A becomes (A + A2)/2 and"
                    " (A - A2)/2 estimates its noise")
    ap.add_argument("--b2", help="an independent render of B (another seed): estimates B's noise")
    ap.add_argument("--b2-spp-ratio", type=float, default=1.0,
                    help="B's samples per pixel over B2's (default 1)")
    ap.add_argument("--diff", help="write A - B (after the transforms) as a PFM")
    args = ap.parse_args()

    a_raw = read_pfm(args.a).astype(np.float64)
    b = read_pfm(args.b).astype(np.float64)
    if a_raw.shape[2] == 1:
        a_raw = np.repeat(a_raw, 3, axis=2)
    if b.shape[2] == 1:
        b = np.repeat(b, 3, axis=2)
    a_half_diff = None
    if args.a2:
        a2 = read_pfm(args.a2).astype(np.float64)
        if a2.shape[2] == 1:
            a2 = np.repeat(a2, 3, axis=2)
        a_half_diff = (a_raw - a2) / 2
        a_raw = (a_raw + a2) / 2
    k = args.downsample_a
    if k > 1:
        a_raw = downsample(a_raw, k)
        if a_half_diff is not None:
            a_half_diff = downsample(a_half_diff, k)
    if a_raw.shape != b.shape:
        sys.exit(f"size mismatch: A {a_raw.shape} vs B {b.shape}")
    a = 1.0 - a_raw if args.one_minus_a else a_raw

    if args.mask_from:
        m = read_pfm(args.mask_from).astype(np.float64)
        if m.shape[:2] != b.shape[:2]:
            m = downsample(m, k)
        mask = m.mean(axis=2) > args.threshold
    else:
        mask = (a_raw.mean(axis=2) > args.threshold) | (b.mean(axis=2) > args.threshold)
    n = int(mask.sum())
    if n == 0:
        sys.exit("no pixel passes the mask")
    am, bm = a[mask], b[mask]  # [n, 3]
    d = am - bm
    out = {
        "pixels": n,
        "of": int(mask.size),
        "rel_rmse": float(np.sqrt(np.mean(d * d)) / np.mean(bm)),
        "rmse": float(np.sqrt(np.mean(d * d))),
        "max_abs": float(np.abs(d).max()),
        "mean_a": float(am.mean()),
        "mean_b": float(bm.mean()),
        "mean_ratio": float(am.mean() / bm.mean()),
        "channel_ratio": [float(am[:, c].mean() / bm[:, c].mean()) for c in range(3)],
        "mean_diff": float(d.mean()),
    }
    noise2 = None
    if a_half_diff is not None:
        na2 = float(np.mean(a_half_diff[mask] ** 2))
        out["noise_rel_rmse_a"] = float(np.sqrt(na2) / np.mean(bm))
        noise2 = na2
    if args.stderr_b and args.b2:
        sys.exit("--stderr-b and --b2 both estimate B's noise: give one")
    if args.b2:
        b2 = read_pfm(args.b2).astype(np.float64)
        if b2.shape[2] == 1:
            b2 = np.repeat(b2, 3, axis=2)
        if b2.shape != b.shape:
            sys.exit(f"size mismatch: B {b.shape} vs B2 {b2.shape}")
        if not args.b2_spp_ratio > 0:
            sys.exit("--b2-spp-ratio must be positive")
        nb2 = float(np.mean((b - b2)[mask] ** 2)) / (1.0 + args.b2_spp_ratio)
        out["noise_rel_rmse_b"] = float(np.sqrt(nb2) / np.mean(bm))
        noise2 = nb2 + (noise2 or 0.0)
    if args.stderr_b:
        e = read_pfm(args.stderr_b).astype(np.float64)
        if e.shape[2] == 1:
            e = np.repeat(e, 3, axis=2)
        nb2 = float(np.mean(e[mask] ** 2))
        out["noise_rel_rmse_b"] = float(np.sqrt(nb2) / np.mean(bm))
        noise2 = nb2 + (noise2 or 0.0)
    if noise2 is not None:
        # What is left of the RMSE once the expected noise is taken out (systematic part).
        out["excess_rel_rmse"] = float(np.sqrt(max(np.mean(d * d) - noise2, 0.0)) / np.mean(bm))
    if args.diff:
        write_pfm(args.diff, np.where(mask[:, :, None], a - b, 0.0))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
