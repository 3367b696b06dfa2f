#!/usr/bin/env python3
"""GPU bytes against max error, per payload family, beside NanoVDB FpN (issue 33, item 4).

For each input (a VDB file or sequence) and each bound E = f × the grid's value range, cooks
with `vdbcook cook INPUT --max-error E --json`, once per payload family: `cheapest` (no
`--format`: per brick the cheapest representation that meets E, packed widths included),
`no-packed` (`--no-packed`: the cheapest of BC7, BC4, unorm8, f16, f32, what cooks gave before
asset format 7), `bc4` (`--format bc4 --no-packed`), `unorm8` and `f16` (`--format F`: that
format wherever it meets E, falling back brick by brick where it does not, so each line is what
choosing that family costs), and reads `bits_per_active_voxel_gpu` and the cook's own NanoVDB
comparison (`nanovdb`: NanoVDB FpN at the same bound, `nanovdb_convert --fpN -a E`). Writes
OUT/results.json, OUT/results.md (the tables) and one SVG chart per input
(OUT/gpu_bits_<name>.svg: GPU bits per active voxel against E, both on log scales).

Usage:
  tools/gpu_bytes/sweep.py --vdbcook target/release/vdbcook -o docs/gpu_bytes \\
      --input wdas=../shared/samples/wdas-cloud/wdas_cloud_sixteenth.vdb \\
      --input smoke1=../shared/samples/openvdb-smoke1/smoke.vdb ...
  (`NAME=PATH` or `NAME=PATH::GRID`; extra cook flags with `NAME=PATH::GRID::--frames 100..199`)

Python 3 standard library only; the charts are plain SVG.
"""

import argparse
import datetime
import json
import math
import os
import platform
import subprocess
import sys

FAMILIES = ["cheapest", "no-packed", "bc4", "unorm8", "f16"]
FLAGS = {"cheapest": [], "no-packed": ["--no-packed"], "bc4": ["--format", "bc4", "--no-packed"],
         "unorm8": ["--format", "unorm8"], "f16": ["--format", "f16"]}
LABELS = {"cheapest": "cheapest (packed included)", "no-packed": "cheapest, --no-packed",
          "bc4": "--format bc4 --no-packed", "unorm8": "--format unorm8", "f16": "--format f16",
          "NanoVDB FpN": "NanoVDB FpN"}
FRACTIONS = [0.002, 0.005, 0.01, 0.02, 0.05, 0.1]
COLOURS = {"cheapest": "#000000", "no-packed": "#1f77b4", "bc4": "#d62728", "unorm8": "#2ca02c",
           "f16": "#9467bd", "NanoVDB FpN": "#ff7f0e"}


def run_json(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    return json.loads(p.stdout)


def value_range(vdbcook, path, grid):
    """min and max of the grid over every file of `path` (`vdbcook inspect --json`; with
    `--frames` in the flags, a bound of the selected frames' range)."""
    d = run_json([vdbcook, "inspect", path, "--json"])
    lo, hi = math.inf, -math.inf
    for f in d["files"]:
        for g in f["grids"]:
            if (grid and g["name"] == grid) or (not grid and g["name"] == "density") or (
                    not grid and len(f["grids"]) == 1):
                if g.get("value_min") is not None:
                    lo, hi = min(lo, g["value_min"]), max(hi, g["value_max"])
    if lo > hi:
        sys.exit(f"{path}: no values for grid {grid or 'density'}")
    return lo, hi


def cook(vdbcook, path, grid, extra, family, e, out):
    cmd = [vdbcook, "cook", path, "-o", out, "--max-error", f"{e:.6g}", "--json"] + extra
    if grid:
        cmd += ["--grid", grid]
    cmd += FLAGS[family]
    d = run_json(cmd)
    os.remove(out)
    reps = d["representations"]
    return {
        "family": family, "max_error": e,
        "gpu_bits": d["bits_per_active_voxel_gpu"], "gpu_bytes": d["bytes"]["topology"] + d["bytes"]["atlas"],
        "file_bits": d["bits_per_active_voxel"],
        "max_abs": d["error"]["max_abs"], "max_abs_any_gpu": d["error"]["max_abs_any_gpu"],
        "rmse": d["error"]["rmse"], "representations": reps,
        "nanovdb_bits": d["nanovdb"]["bits_per_active_voxel"], "nanovdb_bytes": d["nanovdb"]["gpu_bytes"],
        "nanovdb_node_bytes": d["nanovdb"]["node_bytes"], "active_voxels": d["active_voxels"],
        "frames": d["frames"], "encode_s": d["seconds"]["encode"],
    }


def nice_ticks(lo, hi):
    return [m * 10.0 ** k for k in range(-6, 7) for m in (1, 2, 5) if lo <= m * 10.0 ** k <= hi]


def chart(name, rows, title):
    from xml.sax.saxutils import escape
    W, H, L, R, T, B = 840, 480, 70, 600, 50, 420
    xs = [r["fraction"] for r in rows]
    series = {f: [(r["fraction"], r["gpu_bits"]) for r in rows if r["family"] == f] for f in FAMILIES}
    series["NanoVDB FpN"] = sorted({(r["fraction"], r["nanovdb_bits"]) for r in rows if r["family"] == "cheapest"})
    ys = [y for s in series.values() for _, y in s]
    x0, x1 = math.log10(min(xs) / 1.2), math.log10(max(xs) * 1.2)
    ylo = 10 ** math.floor(math.log10(min(ys) * 0.9))
    yhi = 10 ** math.ceil(math.log10(max(ys) * 1.1))
    y0, y1 = math.log10(ylo), math.log10(yhi)

    def X(v):
        return L + (math.log10(v) - x0) / (x1 - x0) * (R - L)

    def Y(v):
        return B - (math.log10(v) - y0) / (y1 - y0) * (B - T)

    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" '
         'font-family="Helvetica, Arial, sans-serif">', f'<rect width="{W}" height="{H}" fill="white"/>',
         f'<text x="{(L + R) / 2}" y="24" text-anchor="middle" font-size="14" font-weight="bold">'
         f'{escape(title)}</text>']
    for v in nice_ticks(10 ** x0, 10 ** x1):
        o.append(f'<line x1="{X(v):.1f}" y1="{T}" x2="{X(v):.1f}" y2="{B}" stroke="#e4e4e4"/>')
        o.append(f'<text x="{X(v):.1f}" y="{B + 16}" text-anchor="middle" font-size="11">{v:g}</text>')
    for v in nice_ticks(ylo, yhi):
        o.append(f'<line x1="{L}" y1="{Y(v):.1f}" x2="{R}" y2="{Y(v):.1f}" stroke="#e4e4e4"/>')
        o.append(f'<text x="{L - 6}" y="{Y(v) + 4:.1f}" text-anchor="end" font-size="11">{v:g}</text>')
    o.append(f'<rect x="{L}" y="{T}" width="{R - L}" height="{B - T}" fill="none" stroke="#333"/>')
    o.append(f'<text x="{(L + R) / 2}" y="{B + 36}" text-anchor="middle" font-size="12">'
             'max error, fraction of the value range (log) — every voxel, as any conformant GPU reads it</text>')
    o.append(f'<text transform="translate({L - 48},{(T + B) / 2}) rotate(-90)" text-anchor="middle" '
             'font-size="12">GPU bits per active voxel (log)</text>')
    for i, (f, pts) in enumerate(series.items()):  # one polyline and legend entry per series
        if not pts:
            continue
        c = COLOURS[f]
        dash = ' stroke-dasharray="6,4"' if f == "NanoVDB FpN" else ""
        o.append('<polyline fill="none" stroke-width="2" stroke="' + c + '"' + dash + ' points="'
                 + " ".join(f"{X(x):.1f},{Y(y):.1f}" for x, y in pts) + '"/>')
        for x, y in pts:
            o.append(f'<circle cx="{X(x):.1f}" cy="{Y(y):.1f}" r="3" fill="{c}"/>')
        ly = T + 14 + 18 * i
        o.append(f'<line x1="{R + 12}" y1="{ly - 4}" x2="{R + 36}" y2="{ly - 4}" stroke="{c}" stroke-width="2"{dash}/>')
        label = LABELS[f]
        o.append(f'<text x="{R + 42}" y="{ly}" font-size="11">{escape(label)}</text>')
    o.append("</svg>")
    return "\n".join(o)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--vdbcook", default="target/release/vdbcook")
    ap.add_argument("-o", "--out", required=True)
    ap.add_argument("--input", action="append", required=True, help="NAME=PATH[::GRID[::FLAGS]]")
    ap.add_argument("--fractions", default=",".join(map(str, FRACTIONS)))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    fractions = [float(x) for x in a.fractions.split(",")]
    res = {"machine": f"{platform.node()} ({os.cpu_count()} cores)",
           "date": datetime.date.today().isoformat(), "inputs": []}
    for spec in a.input:
        name, rest = spec.split("=", 1)
        parts = rest.split("::")
        path, grid = parts[0], (parts[1] if len(parts) > 1 and parts[1] else None)
        extra = parts[2].split() if len(parts) > 2 else []
        lo, hi = value_range(a.vdbcook, path, grid)
        rows = []
        for f in fractions:
            for fam in FAMILIES:
                r = cook(a.vdbcook, path, grid, extra, fam, f * (hi - lo),
                         os.path.join(a.out, f".sweep-{name}.vdbc"))
                r["fraction"] = f
                rows.append(r)
                print(f"{name} E={f:g}·range {fam:7s} GPU {r['gpu_bits']:.3f} bit/voxel, "
                      f"NanoVDB FpN {r['nanovdb_bits']:.3f}", file=sys.stderr)
        res["inputs"].append({"name": name, "path": path, "grid": grid, "flags": extra,
                              "value_range": [lo, hi], "rows": rows})
        title = f"{name}: GPU bits per active voxel against max error"
        with open(os.path.join(a.out, f"gpu_bits_{name}.svg"), "w") as fh:
            fh.write(chart(name, rows, title))
    with open(os.path.join(a.out, "results.json"), "w") as fh:
        json.dump(res, fh, indent=1)
    md = [f"GPU bits per active voxel (topology + atlas) against `--max-error` = fraction × value range; "
          f"{res['machine']}, {res['date']}; `tools/gpu_bytes/sweep.py`.", ""]
    for inp in res["inputs"]:
        md += [f"### {inp['name']} (`{inp['path']}`{', grid ' + inp['grid'] if inp['grid'] else ''}"
               f"{' ' + ' '.join(inp['flags']) if inp['flags'] else ''}; range "
               f"{inp['value_range'][0]:.4g} .. {inp['value_range'][1]:.4g}, "
               f"{inp['rows'][0]['frames']} frame(s), {inp['rows'][0]['active_voxels']:,} active voxels)", "",
               "| E / range | " + " | ".join(FAMILIES) + " | NanoVDB FpN | cheapest / NanoVDB | cheapest max error (any GPU) / E | cheapest RMSE / E (no-packed) |",
               "|---:|" + "---:|" * (len(FAMILIES) + 4)]
        for f in fractions:
            rs = {r["family"]: r for r in inp["rows"] if r["fraction"] == f}
            c, o = rs["cheapest"], rs["no-packed"]
            md.append(f"| {f:g} | " + " | ".join(f"{rs[x]['gpu_bits']:.2f}" for x in FAMILIES)
                      + f" | {c['nanovdb_bits']:.2f} | {c['gpu_bytes'] / c['nanovdb_bytes']:.3f}"
                      f" | {c['max_abs_any_gpu'] / c['max_error']:.3f}"
                      f" | {c['rmse'] / c['max_error']:.3f} ({o['rmse'] / o['max_error']:.3f}) |")
        md.append("")
    with open(os.path.join(a.out, "results.md"), "w") as fh:
        fh.write("\n".join(md))
    print("\n".join(md))


if __name__ == "__main__":
    main()
