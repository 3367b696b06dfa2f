#!/usr/bin/env python3
"""The engine drawer's reduced-resolution march: its cost against its error, charted.

Issue 34 item 3 asks for the lit march within 2x the density march and for the optional half-
and quarter-resolution march's error charted. This runs `vdbcook bench` on each asset at each
`--march-resolution` (alternating the assets and resolutions, `--rounds` times), keeps every
run's JSON, and draws one SVG: the median of the lit static frame's GPU ms over the median of
the full-resolution density static frame's (x) against the lit `resolution_error`, the static
frame's relative RMSE against the full-resolution lit draw (y, log). The full march has no
error: it is drawn on the x axis, labelled "none" (the y axis runs from 1e-4 up; an error below
it would be drawn there too). The table printed on stdout has every
median and each round's own lit / full-density ratio.

    python3 tools/lighting/resolution_chart.py --bin target/release/vdbcook \\
        --asset stormscape=/tmp/storm.vdbc --asset wdas=/tmp/wdas.vdbc \\
        --asset fire=/tmp/fire.vdbc --out docs/images/march_resolution_error_cost.svg

`--jsonl FILE` keeps the runs (one bench JSON a line, with `name` and `round` added); with
`--from FILE` nothing is run and the chart is drawn from those lines. Needs Python 3 only. Like
the rest of tools/, it is run by people, not by cargo or CI; on a 2-core VM with lavapipe a round
of three assets takes about 8 minutes.
"""

import argparse
import json
import math
import os
import statistics
import subprocess
import sys

RESOLUTIONS = ["full", "half", "quarter"]
COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"]


def run_bench(binary, path, resolution, runs):
    cmd = [binary, "bench", path, "--modes", "density,lit", "--march-resolution", resolution,
           "--frames", "1", "--runs", str(runs), "--json"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stderr}")
    return json.loads(done.stdout)


def summarize(lines):
    """{asset: {resolution: {density, lit, error, density_full}}} as medians over rounds."""
    by = {}
    full_density = {}
    for d in lines:
        r = d.get("march_resolution", "full")
        modes = {x["mode"]: x for x in d["results"]}
        modes["round"] = d["round"]
        by.setdefault(d["name"], {}).setdefault(r, []).append(modes)
        if r == "full":
            full_density.setdefault(d["name"], {})[d["round"]] = modes["density"]["static_ms"]
    out = {}
    for asset, per in by.items():
        if asset not in full_density:
            sys.exit(f"{asset}: no full-resolution run to measure against")
        base = statistics.median(full_density[asset].values())
        out[asset] = {}
        for r, runs in per.items():
            lit = statistics.median(m["lit"]["static_ms"] for m in runs)
            den = statistics.median(m["density"]["static_ms"] for m in runs)
            errs = [m["lit"].get("resolution_error") for m in runs]
            errs = [e for e in errs if e is not None]
            derrs = [m["density"].get("resolution_error") for m in runs]
            derrs = [e for e in derrs if e is not None]
            out[asset][r] = {
                "lit_ms": lit,
                "density_ms": den,
                "lit_over_full_density": lit / base,
                "rounds_ratio": [m["lit"]["static_ms"] / full_density[asset][m["round"]]
                                 for m in runs if m["round"] in full_density[asset]],
                "lit_error": statistics.median(errs) if errs else None,
                "density_error": statistics.median(derrs) if derrs else None,
                "rounds": len(runs),
            }
    return out


def chart(summary, adapter, path):
    w, h, left, right, top, bottom = 720, 430, 80, 560, 40, 370
    xs = [v["lit_over_full_density"] for a in summary.values() for v in a.values()]
    xmax = max(4.0, math.ceil(max(xs) / 2.0) * 2.0)
    ylo, yhi = 1e-4, 1.0

    def px(x):
        return left + (right - left) * x / xmax

    def py(e):
        if e is None:
            return bottom + 0.0  # no error (the full march): on the axis, below the 1e-4 tick
        e = min(max(e, ylo), yhi)
        return bottom - (bottom - top) * (math.log10(e) - math.log10(ylo)) / (
            math.log10(yhi) - math.log10(ylo))

    s = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
         'font-family="sans-serif" font-size="12">',
         '<rect width="100%" height="100%" fill="white"/>',
         f'<line x1="{left}" y1="{bottom}" x2="{right}" y2="{bottom}" stroke="black"/>',
         f'<line x1="{left}" y1="{top}" x2="{left}" y2="{bottom}" stroke="black"/>']
    step = 2 if xmax <= 24 else 5
    for i in range(0, int(xmax) + 1, step):
        x = px(i)
        s.append(f'<line x1="{x:.1f}" y1="{bottom}" x2="{x:.1f}" y2="{bottom + 5}" stroke="black"/>'
                 f'<text x="{x:.1f}" y="{bottom + 18}" text-anchor="middle">{i}</text>')
    for k in range(-3, 1):
        y = py(10.0 ** k)
        s.append(f'<line x1="{left - 5}" y1="{y:.1f}" x2="{left}" y2="{y:.1f}" stroke="black"/>'
                 f'<text x="{left - 8}" y="{y + 4:.1f}" text-anchor="end">1e{k}</text>')
    s.append(f'<line x1="{left - 5}" y1="{bottom}" x2="{left}" y2="{bottom}" stroke="black"/>'
             f'<text x="{left - 8}" y="{bottom + 4}" text-anchor="end">none</text>')
    x2 = px(2.0)
    s.append(f'<line x1="{x2:.1f}" y1="{top}" x2="{x2:.1f}" y2="{bottom}" stroke="#999" '
             f'stroke-dasharray="4,3"/><text x="{x2 + 4:.1f}" y="{top + 12}" fill="#666">'
             'issue 34: 2×</text>')
    s.append(f'<text x="{(left + right) / 2}" y="{h - 22}" text-anchor="middle">lit static ms / '
             'full-resolution density static ms</text>')
    s.append(f'<text x="{left - 60}" y="{top - 16}">lit image error against the full march '
             '(relative RMSE; the full march has none: on the axis)</text>')
    s.append(f'<text x="{left}" y="{h - 6}" fill="#666">{adapter}; vdbcook bench '
             '--march-resolution R, medians</text>')
    for i, (asset, per) in enumerate(summary.items()):
        c = COLOURS[i % len(COLOURS)]
        pts = [(per[r]["lit_over_full_density"], per[r]["lit_error"], r)
               for r in RESOLUTIONS if r in per]
        s.append('<polyline fill="none" stroke="{}" points="{}"/>'.format(
            c, " ".join(f"{px(x):.1f},{py(e):.1f}" for x, e, _ in pts)))
        for x, e, r in pts:
            s.append(f'<circle cx="{px(x):.1f}" cy="{py(e):.1f}" r="4" fill="{c}"/>'
                     f'<text x="{px(x) + 6:.1f}" y="{py(e) - 6:.1f}" fill="{c}">{r}</text>')
        ly = top + 10 + 18 * i
        s.append(f'<rect x="{right + 20}" y="{ly - 9}" width="10" height="10" fill="{c}"/>'
                 f'<text x="{right + 36}" y="{ly}">{asset}</text>')
    s.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(s) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", help="the vdbcook binary (copy it first if it may be rebuilt)")
    ap.add_argument("--asset", action="append", default=[], metavar="NAME=PATH")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--runs", type=int, default=5, help="static draws timed per bench run")
    ap.add_argument("--jsonl", help="append every run's JSON here")
    ap.add_argument("--from", dest="source", help="chart these JSON lines, run nothing")
    ap.add_argument("--out", required=True, help="the SVG to write")
    a = ap.parse_args()
    assets = []
    for spec in a.asset:
        name, eq, path = spec.partition("=")
        if not eq or not name or not path:
            ap.error(f"--asset {spec}: NAME=PATH")
        if not os.path.exists(path):
            ap.error(f"--asset {spec}: {path}: no such file")
        assets.append((name, path))
    lines = []
    if a.source:
        with open(a.source) as f:
            lines = [json.loads(l) for l in f if l.strip()]
    else:
        if not a.bin or not assets:
            ap.error("--bin and at least one --asset, or --from")
        if not os.access(a.bin, os.X_OK):
            ap.error(f"--bin {a.bin}: not an executable")
        for k in range(a.rounds):
            for name, path in assets:
                for r in RESOLUTIONS:
                    d = run_bench(a.bin, path, r, a.runs)
                    d["name"], d["round"] = name, k + 1
                    lines.append(d)
                    if a.jsonl:
                        with open(a.jsonl, "a") as f:
                            f.write(json.dumps(d) + "\n")
                    print(f"round {k + 1} {name} {r}", file=sys.stderr, flush=True)
    if not lines:
        sys.exit("no runs")
    summary = summarize(lines)
    chart(summary, lines[0].get("adapter", "?"), a.out)
    print("| asset | march | density ms | lit ms | lit / full density (each round) | error density "
          "| error lit |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for asset, per in summary.items():
        for r in RESOLUTIONS:
            if r in per:
                v = per[r]
                fmt = lambda e: "–" if e is None else f"{e:.4f}"
                each = " / ".join(f"{x:.2f}" for x in v["rounds_ratio"])
                print(f"| {asset} | {r} | {v['density_ms']:.1f} | {v['lit_ms']:.1f} | "
                      f"{v['lit_over_full_density']:.2f}× ({each}) | {fmt(v['density_error'])} | "
                      f"{fmt(v['lit_error'])} |")


if __name__ == "__main__":
    main()
