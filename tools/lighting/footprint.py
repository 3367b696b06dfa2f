#!/usr/bin/env python3
"""Primary rays by pixel footprint (`render --mode lit --primary-lod`) against the pixel-area
mean: renders an asset cooked with `--lod` at small sizes with and without `--primary-lod`, and a
full-resolution render `--factor` times larger box-downsampled to each size (the mean radiance
over each pixel's area, the truth a footprint method approximates), and prints each image's
relative RMSE (where the truth exceeds 0.001) and mean ratio to it. A tool for people, like
sweep.py: nothing here runs in cargo or CI.

    python3 tools/lighting/footprint.py --bin target/release/vdbcook --asset /tmp/wdas_lod.vdbc \
        --width 80 --width 160 --width 320
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "mitsuba"))
from pfm import read_pfm  # noqa: E402


def render(bin_, asset, out, w, h, extra):
    cmd = [bin_, "render", asset, "-o", out, "--mode", "lit", "--backend", "cpu",
           "--width", str(w), "--height", str(h)] + extra
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return read_pfm(out).astype(np.float64)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--asset", required=True, help="a cooked asset with levels (cook --lod all)")
    ap.add_argument("--width", type=int, action="append", required=True,
                    help="image width (height 9/16 of it); repeat for several")
    ap.add_argument("--factor", type=int, default=8, help="supersampling of the truth per axis")
    ap.add_argument("--camera", help="render's --camera (default: the default framing)")
    a = ap.parse_args()
    cam = ["--camera", a.camera] if a.camera else []
    with tempfile.TemporaryDirectory() as d:
        print("| width | footprint method | rel RMSE vs pixel-area mean | mean ratio |")
        print("|---|---|---|---|")
        for w in a.width:
            h = w * 9 // 16
            truth = render(a.bin, a.asset, f"{d}/t.pfm", w * a.factor, h * a.factor, cam)
            truth = truth.reshape(h, a.factor, w, a.factor, -1).mean((1, 3))
            m = truth.mean(2) > 0.001
            for name, extra in [("full resolution (point)", []), ("--primary-lod", ["--primary-lod"])]:
                x = render(a.bin, a.asset, f"{d}/x.pfm", w, h, cam + extra)
                err = np.sqrt(((x - truth)[m] ** 2).mean()) / truth[m].mean()
                print(f"| {w} | {name} | {err:.4f} | {x[m].mean() / truth[m].mean():.4f} |")


if __name__ == "__main__":
    main()
