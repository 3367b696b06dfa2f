#!/usr/bin/env python3
"""Speed against accuracy of vdbcook's lighting methods, on a few scenes, in one table.

Why this exists: `vdbcook render` has several ways to light a volume that trade time for
fidelity, and their knobs (light-volume resolution, march step, multiple-scattering octaves)
were tuned once by hand (see the lit mode's notes in docs/rendering.md). This script re-measures
all of them the same way, so a change to a renderer or a default can be judged by "how much
error per millisecond" rather than by eye:

  lit        the light-volume renderer (`--mode lit`), default settings, on CPU and GPU, and
             one knob changed at a time: --ms-octaves 1 --ms-sky 16 (about single
             scattering),
             --light-res 16/32/128, --step 0.5/2/4
  scatter    vdb_render's single scattering with exact per-sample shadow marches (`--gain 0`,
             so the shadows are physical). It has no sky, an isotropic phase and no multiple
             scattering, so its error is large by construction; it is the timing baseline of
             "exact shadow marches"
  density    the plain density march: timing only (it is not a lit image, no error)
  reference  the CPU path tracer at low sample counts (16 and 64 spp, a seed other than the
             converged reference's): its time, and how far a short path trace is from converged

Every image is compared with a converged path-traced reference of the same scene, camera and
size by tools/mitsuba/compare.py (run as is, so the metric is exactly that script's):
rel_rmse = sqrt(mean((a - b)^2)) / mean(b) and mean_ratio = mean(a) / mean(b), over the pixels
where the reference exceeds --threshold (the same pixels for every method of a scene).
The highest-spp reference row doubles as a check of the converged reference: its mean ratio
must be 1 within --ref-tol, else the reference was made with other settings or another binary
and the table says so.

Timing: the CPU time is the CLI's `render_seconds` (light-volume build + march for lit); the GPU
time is its `gpu_ms`, GPU timestamps around the trace pass of a render made after an untimed
warm-up — for lit the light volume is built in that warm-up, so gpu_ms is the march alone; the
GPU row's wall seconds (`render_seconds`: upload, pipeline creation, warm-up, timed render,
read-back) are kept too. A method whose first run takes under --repeat-under seconds is run
--runs times and the median is reported; the runs are interleaved (every method once, then the
fast ones again, ...) so that a shared machine's changing load hits all methods alike. Renders
run one at a time. Every run writes the same image (the renders are deterministic); the last
one is scored.

Outputs in OUT: results.json (every run, every compare.py field, the machine), results.md (the
table), chart_cpu.svg and chart_gpu.svg (time against rel RMSE, one point per row, see
chart_svg), pfm/ (one image per row), refs/ (references rendered with --ref-spp).
`--chart-only OUT` rebuilds results.md and the charts from OUT/results.json, rendering nothing.

Example (the three scenes of the lit-mode tuning, converged references made beforehand):

  python3 tools/lighting/sweep.py --bin target/release/vdbcook \\
      --asset /tmp/lit/wdas.vdbc --asset /tmp/lit/storm.vdbc --asset /tmp/lit/smoke.vdbc \\
      --ref-pattern '/tmp/lit/r/{scene}_ref3.pfm' --out /tmp/lit/sweep

Needs Python 3 and numpy (for ../mitsuba/pfm.py and compare.py). Does not build anything.
"""
import argparse
import datetime
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
MITSUBA = os.path.join(HERE, "..", "mitsuba")
COMPARE = os.path.join(MITSUBA, "compare.py")
sys.dont_write_bytecode = True  # leave no __pycache__ in tools/mitsuba
sys.path.insert(0, MITSUBA)
from pfm import read_pfm  # noqa: E402

LIT_DEFAULT = ("diffusion (sun and sky), light-res 64, sun-near 3, near-scatter 0.5, march auto,"
               " step 1")

# (id, mode, extra CLI args, settings shown in the table, compared with the reference?)
LIT_METHODS = [
    ("lit", "lit", [], LIT_DEFAULT, True),
    ("lit-oct", "lit", ["--ms-model", "octaves"],
     "--ms-model octaves (8 oct, ms 0.98,0.9,0.6, ms-sky 0.25)", True),
    ("lit-ss", "lit", ["--ms-model", "octaves", "--ms-octaves", "1", "--ms-sky", "16"],
     "--ms-model octaves --ms-octaves 1 --ms-sky 16 (about single scattering)", True),
    ("lit-vox", "lit", ["--march", "voxels"], "--march voxels (each voxel exact)", True),
    ("lit-steps", "lit", ["--march", "steps"], "--march steps (every step, jittered)", True),
    ("lit-near0", "lit", ["--sun-near", "0"], "--sun-near 0 (the light volume alone)", True),
    ("lit-ns0", "lit", ["--near-scatter", "0"],
     "--near-scatter 0 (the solve's cells alone, no once-scattered light below them)", True),
    ("lit-lr16", "lit", ["--light-res", "16"], "--light-res 16", True),
    ("lit-lr32", "lit", ["--light-res", "32"], "--light-res 32", True),
    ("lit-lr128", "lit", ["--light-res", "128"], "--light-res 128", True),
    ("lit-step0.5", "lit", ["--step", "0.5"], "--step 0.5", True),
    ("lit-step2", "lit", ["--step", "2"], "--step 2", True),
    ("lit-step4", "lit", ["--step", "4"], "--step 4", True),
]
OTHER_METHODS = [
    ("scatter", "scatter", ["--gain", "0"], "--gain 0 (exact shadows; no sky, isotropic, no MS)", True),
    ("density", "density", [], "plain density march (timing only)", False),
]


def method_list(args):
    """[(id, mode, backend, extra args, settings, compare)] in table order."""
    gpu = [] if args.no_gpu else ["gpu"]
    out = []
    for mid, mode, extra, settings, cmp in LIT_METHODS:
        backends = ["cpu"] + (gpu if (mid in ("lit", "lit-oct", "lit-vox", "lit-steps", "lit-near0", "lit-ns0") or args.gpu_variants) else [])
        out += [(mid, mode, b, extra, settings, cmp) for b in backends]
    for mid, mode, extra, settings, cmp in OTHER_METHODS:
        out += [(mid, mode, b, extra, settings, cmp) for b in ["cpu"] + gpu]
    for spp in args.ref_rows:
        out.append((f"reference-{spp}", "reference", "cpu",
                    ["--spp", str(spp), "--seed", str(args.ref_seed)],
                    f"--spp {spp} --seed {args.ref_seed}", True))
    if args.only:
        keep = set(args.only)
        out = [m for m in out if m[0] in keep or m[1] in keep]
    return out


def render(args, asset, out_pfm, mode, backend, extra):
    # --transparent: the directly seen sky stays out of the image, so the reference's mask
    # (> threshold) is the volume's pixels alone. Until 2026-11-26 every PFM carried the sky as
    # its background and the scores counted it: WDAS's lit mode read 0.981 / 0.075 (mean ratio /
    # rel RMSE) over all pixels where it is 0.909 / 0.137 over the cloud's.
    cmd = [args.bin, "render", asset, "--mode", mode, "--backend", backend, "--transparent",
           "--width", str(args.width), "--height", str(args.height), "-o", out_pfm, "--json"] + extra
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}\nexit {p.returncode}: {p.stderr.strip()}")
    j = json.loads(p.stdout)
    return cmd, {"render_seconds": j["render_seconds"], "gpu_ms": j.get("gpu_ms"),
                 "process_seconds": wall, "load1": load, "threads": j.get("threads"),
                 "adapter": j.get("adapter")}


def compare(a, ref, threshold):
    p = subprocess.run([sys.executable, COMPARE, a, ref, "--mask-from", ref,
                        "--threshold", str(threshold)], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"compare.py {a} {ref}: {p.stderr.strip() or p.stdout.strip()}")
    return json.loads(p.stdout)


def median(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else None


def scene_name(asset):
    return os.path.splitext(os.path.basename(asset))[0]


def find_ref(args, scene, asset):
    """The converged reference of `scene`: --ref, else --ref-pattern, else render one."""
    path = args.refs.get(scene) or (args.ref_pattern.format(scene=scene) if args.ref_pattern else None)
    if path and os.path.exists(path):
        return path, None
    if not args.ref_spp:
        return None, f"no reference ({path or 'none given'}) and no --ref-spp: errors left out"
    os.makedirs(os.path.join(args.out, "refs"), exist_ok=True)
    path = os.path.join(args.out, "refs", f"{scene}_ref{args.ref_spp}.pfm")
    if not os.path.exists(path):
        print(f"[{scene}] rendering a {args.ref_spp}-spp reference -> {path}", flush=True)
        render(args, asset, path, "reference", "cpu", ["--spp", str(args.ref_spp), "--seed", "1"])
    return path, f"reference rendered here at {args.ref_spp} spp (seed 1)"


def fmt(x, nd):
    return "–" if x is None else f"{x:.{nd}f}"


def fmt_ms(x):
    if x is None:
        return "–"
    return f"{x:.0f}" if x >= 100 else (f"{x:.1f}" if x >= 10 else f"{x:.2f}")


def markdown(res):
    lines = [
        f"Sweep of {res['date']} on {res['machine']}; binary `{res['bin']}` ({res['bin_version']}); "
        f"{res['width']}×{res['height']}; compare.py mask: reference > {res['threshold']}.",
        "",
        "| scene | method | backend | settings | time ms | wall s | rel RMSE | mean ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in res["rows"]:
        c = r.get("compare") or {}
        t = r["gpu_ms"] if r["backend"] == "gpu" else (r["render_seconds"] or 0) * 1e3 or None
        lines.append(
            f"| {r['scene']} | {r['method']} | {r['backend']} | {r['settings']} | {fmt_ms(t)} | "
            f"{fmt(r['render_seconds'], 2)} | {fmt(c.get('rel_rmse'), 3)} | {fmt(c.get('mean_ratio'), 3)} |")
    lines += ["", "time ms: CPU = render_seconds (lit: light-volume build + march); GPU = gpu_ms, the "
              "trace pass after an untimed warm-up (lit: the march alone, the light volume was built in "
              "the warm-up). wall s = render_seconds (GPU: upload + pipelines + warm-up + render + "
              "read-back). Median of the runs where a run took under "
              f"{res['repeat_under']} s ({res['runs']} runs), else one run.", ""]
    for s in res["scenes"]:
        lines.append(f"- {s['scene']}: reference `{s['ref']}`"
                     + (f" — {s['note']}" if s.get("note") else "")
                     + (f"; check: {s['ref_check']}" if s.get("ref_check") else ""))
    return "\n".join(lines) + "\n"


# One (colour, marker) per scene in the charts, in scene order (then round again).
CHART_STYLES = [("#1f77b4", "circle"), ("#d62728", "square"), ("#2ca02c", "triangle"),
                ("#9467bd", "diamond"), ("#ff7f0e", "triangle-down"), ("#17becf", "circle"),
                ("#8c564b", "square"), ("#e377c2", "triangle")]


def _nice_step(span, want=6):
    """A round tick step (1, 2, 2.5 or 5 × 10^k) giving about `want` ticks over `span`."""
    raw = span / want
    k = 10 ** math.floor(math.log10(raw))
    return next(m * k for m in (1, 2, 2.5, 5, 10) if m * k >= raw)


def chart_svg(res, backend, clip_factor=5.0):
    """One speed-against-accuracy chart of `backend`'s rows as SVG text ('' if no row qualifies).

    x: the row's time in ms on a log scale (cpu: render_seconds × 1000, so lit = light-volume
    build + march; gpu: gpu_ms, so lit = the march alone); y: compare.py's rel_rmse against the
    converged reference, linear from 0. Rows without an error (density, no reference) or
    without a time are left out. Each scene gets a colour and a marker shape, each point its
    method's name. An error above `clip_factor` × the median error (scatter's 4–6 would squash
    everything else to the floor) is drawn on the top edge as an open marker with an arrow and
    its value in the label.
    """
    from xml.sax.saxutils import escape
    pts = []
    for r in res["rows"]:
        if r["backend"] != backend:
            continue
        err = (r.get("compare") or {}).get("rel_rmse")
        t = r.get("gpu_ms") if backend == "gpu" else (
            r["render_seconds"] * 1e3 if r.get("render_seconds") else None)
        if err is not None and t:
            pts.append((r["scene"], r["method"], t, err))
    if not pts:
        return ""
    scenes = list(dict.fromkeys(p[0] for p in pts))
    style = {s: CHART_STYLES[i % len(CHART_STYLES)] for i, s in enumerate(scenes)}

    W, H = 860, 540
    L, R, T, B = 70, 650, 58, 470  # the plot area
    fs = 9  # label font size; a character is about 0.6 fs wide

    # y: linear from 0 to a round top above every unclipped error.
    cap = clip_factor * statistics.median(p[3] for p in pts)
    top = max([p[3] for p in pts if p[3] <= cap] or [cap]) or 1.0
    ystep = _nice_step(top)
    ytop = ystep * math.ceil(top / ystep * 1.04)
    # x: log10, from the 1-2-5 value below the fastest time to the one above the slowest.
    ticks = [m * 10.0 ** d for d in range(-3, 7) for m in (1, 2, 5)]
    lo = max([v for v in ticks if v <= 0.9 * min(p[2] for p in pts)] or ticks[:1])
    hi = min([v for v in ticks if v >= 1.1 * max(p[2] for p in pts)] or ticks[-1:])
    ticks = [v for v in ticks if lo <= v <= hi]
    x0, x1 = math.log10(lo), math.log10(hi)

    def X(ms):
        return L + (math.log10(ms) - x0) / (x1 - x0) * (R - L)

    def Y(e):
        return B - min(e, ytop) / ytop * (B - T)

    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" '
         f'font-family="Helvetica, Arial, sans-serif">',
         f'<rect width="{W}" height="{H}" fill="white"/>']
    what = ("CPU: render_seconds (lit: light-volume build + march)" if backend == "cpu"
            else "GPU: gpu_ms (lit: the march alone, light volume cached)")
    o.append(f'<text x="{W / 2}" y="22" text-anchor="middle" font-size="15" font-weight="bold">'
             f'Lighting methods, {backend.upper()}: time against error from the reference</text>')
    o.append(f'<text x="{W / 2}" y="40" text-anchor="middle" font-size="11" fill="#444">'
             f'{escape(res["machine"])} · {escape(res["date"])} · {res["width"]}×{res["height"]}</text>')
    # Grid, ticks, tick labels.
    for v in ticks:
        x = X(v)
        major = abs(math.log10(v) - round(math.log10(v))) < 1e-9  # a power of ten
        o.append(f'<line x1="{x:.1f}" y1="{T}" x2="{x:.1f}" y2="{B}" stroke="'
                 + ("#ddd" if major else "#f0f0f0") + '"/>')
        o.append(f'<line x1="{x:.1f}" y1="{B}" x2="{x:.1f}" y2="{B + (6 if major else 3)}" stroke="#333"/>')
        if major or x1 - x0 <= 3:
            o.append(f'<text x="{x:.1f}" y="{B + 18}" text-anchor="middle" font-size="11"'
                     + ('' if major else ' fill="#666"') + f'>{v:g}</text>')
    k = 0
    while k * ystep <= ytop + 1e-12:
        y = Y(k * ystep)
        o.append(f'<line x1="{L}" y1="{y:.1f}" x2="{R}" y2="{y:.1f}" stroke="#ddd"/>')
        o.append(f'<line x1="{L - 5}" y1="{y:.1f}" x2="{L}" y2="{y:.1f}" stroke="#333"/>')
        o.append(f'<text x="{L - 8}" y="{y + 4:.1f}" text-anchor="end" font-size="11">{k * ystep:g}</text>')
        k += 1
    o.append(f'<rect x="{L}" y="{T}" width="{R - L}" height="{B - T}" fill="none" stroke="#333"/>')
    o.append(f'<text x="{(L + R) / 2}" y="{B + 38}" text-anchor="middle" font-size="12">'
             f'time, ms (log scale) — {what}</text>')
    o.append(f'<text transform="translate({L - 46},{(T + B) / 2}) rotate(-90)" text-anchor="middle" '
             f'font-size="12">rel RMSE against the converged reference</text>')

    def marker(shape, x, y, colour, r=4.5, filled=True):
        paint = f'fill="{colour}"' if filled else f'fill="white" stroke="{colour}" stroke-width="1.5"'
        if shape == "circle":
            return f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{r}" {paint}/>'
        if shape == "square":
            return f'<rect x="{x - r * .85:.1f}" y="{y - r * .85:.1f}" width="{r * 1.7:.1f}" height="{r * 1.7:.1f}" {paint}/>'
        pts_ = {"triangle": [(0, -1.2), (1.1, .8), (-1.1, .8)],
                "triangle-down": [(0, 1.2), (1.1, -.8), (-1.1, -.8)],
                "diamond": [(0, -1.3), (1.1, 0), (0, 1.3), (-1.1, 0)]}[shape]
        return ('<polygon points="' + " ".join(f"{x + a * r:.1f},{y + b * r:.1f}" for a, b in pts_)
                + f'" {paint}/>')

    # Markers; then each label, greedily, at the spot near its point (tried nearest first, in
    # 12 directions) that overlaps the least of the markers and labels placed so far, with a
    # leader line when it had to move away from its point.
    boxes = []  # (x0, y0, x1, y1) of markers and labels already placed
    marks, todo = [], []
    for s, mid, t, e in pts:
        x, y = X(t), Y(e)
        colour, shape = style[s]
        clipped = e > ytop
        marks.append(marker(shape, x, y, colour, filled=not clipped))
        if clipped:
            marks.append(f'<path d="M{x:.1f},{y - 7:.1f} l0,-9 m-3,3 l3,-3 l3,3" stroke="{colour}" fill="none"/>')
        boxes.append((x - 5, y - 5, x + 5, y + 5))
        todo.append((x, y, colour, mid + (f" ({e:.2f})" if clipped else ""), mid == "lit"))

    def overlap(a, b):
        return max(0, min(a[2], b[2]) - max(a[0], b[0])) * max(0, min(a[3], b[3]) - max(a[1], b[1]))

    leaders, labels = [], []
    for x, y, colour, text, bold in todo:
        w, h = 0.58 * fs * len(text) * (1.1 if bold else 1) + 2, fs + 2
        best = None
        for dist in (7, 15, 26, 40, 56):
            for deg in (0, 180, 30, -30, 150, -150, 90, -90, 60, -60, 120, -120):
                c, sn = math.cos(math.radians(deg)), math.sin(math.radians(deg))
                ax, ay = x + dist * c, y - dist * sn
                anchor = "start" if c > 0.3 else "end" if c < -0.3 else "middle"
                lx = {"start": ax, "end": ax - w, "middle": ax - w / 2}[anchor]
                top = ay - h / 2 if abs(sn) < 0.6 else (ay - h if sn > 0 else ay)
                box = (lx, top, lx + w, top + h)
                cost = sum(overlap(box, b) for b in boxes) + dist * 2
                if box[0] < L + 1 or box[2] > R - 1 or box[1] < T - 16 or box[3] > B - 1:
                    cost += 1e5
                if best is None or cost < best[0]:
                    best = (cost, dist, ax, anchor, box)
        _, dist, ax, anchor, box = best
        boxes.append(box)
        if dist > 7:
            cx, cy = min(max(x, box[0]), box[2]), min(max(y, box[1]), box[3])
            leaders.append(f'<line x1="{x:.1f}" y1="{y:.1f}" x2="{cx:.1f}" y2="{cy:.1f}" '
                           f'stroke="{colour}" stroke-width="0.6" opacity="0.7"/>')
        labels.append(f'<text x="{ax:.1f}" y="{box[3] - 3:.1f}" text-anchor="{anchor}" font-size="{fs}" '
                      f'fill="{colour}"'
                      + (' font-weight="bold"' if bold else '') + f'>{escape(text)}</text>')
    o += leaders + marks + labels

    # Legend, right of the plot.
    lx, ly = R + 22, T + 8
    o.append(f'<text x="{lx}" y="{ly}" font-size="12" font-weight="bold">scene</text>')
    for i, s in enumerate(scenes):
        colour, shape = style[s]
        yy = ly + 20 + 20 * i
        o.append(marker(shape, lx + 6, yy - 4, colour))
        o.append(f'<text x="{lx + 18}" y="{yy}" font-size="12">{escape(s)}</text>')
    ny = ly + 20 + 20 * len(scenes) + 12
    notes = ["Each point: one method", "(see tools/lighting/README.md);",
             "bold: lit at its defaults.", "Lower is more accurate,", "left is faster."]
    if any(p[3] > ytop for p in pts):
        notes += ["Open marker + arrow: error", f"above {clip_factor:g}× the median,",
                  "drawn at the top; its value", "is in the label."]
    for i, n in enumerate(notes):
        o.append(f'<text x="{lx}" y="{ny + 15 * i}" font-size="10" fill="#444">{escape(n)}</text>')
    o.append("</svg>")
    return "\n".join(o) + "\n"


def write_charts(res, out):
    """Write OUT/chart_cpu.svg and OUT/chart_gpu.svg (a backend with no scored, timed row gets none)."""
    written = []
    for backend in ("cpu", "gpu"):
        svg = chart_svg(res, backend)
        if svg:
            path = os.path.join(out, f"chart_{backend}.svg")
            with open(path, "w") as f:
                f.write(svg)
            written.append(path)
    return written


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", help="the vdbcook binary (copy it if it may be rebuilt meanwhile); required")
    ap.add_argument("--asset", action="append",
                    help="a cooked asset (.vdbc); repeat for more scenes. Scene name = file stem; required")
    ap.add_argument("--ref", action="append", default=[], metavar="SCENE=PFM",
                    help="the converged reference of a scene (linear PFM, same camera/size/settings)")
    ap.add_argument("--ref-pattern", help="reference path with {scene}, e.g. '/refs/{scene}_ref.pfm'")
    ap.add_argument("--ref-spp", type=int, help="render a missing reference at this many spp (seed 1)")
    ap.add_argument("--out", help="output folder (results.json, results.md, chart_*.svg, pfm/); required")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=90)
    ap.add_argument("--runs", type=int, default=3, help="runs of a fast method; the median is reported")
    ap.add_argument("--repeat-under", type=float, default=5.0,
                    help="repeat a method only when its first run's render_seconds is below this")
    ap.add_argument("--ref-rows", type=int, nargs="*", default=[16, 64],
                    help="spp of the low-sample reference rows (also the reference check)")
    ap.add_argument("--ref-seed", type=int, default=11,
                    help="seed of those rows; not one the converged reference used")
    ap.add_argument("--ref-tol", type=float, default=0.03,
                    help="|mean ratio - 1| of the highest-spp reference row above which the "
                    "converged reference is flagged as not matching")
    ap.add_argument("--threshold", type=float, default=1e-3, help="compare.py --threshold")
    ap.add_argument("--no-gpu", action="store_true", help="CPU rows only")
    ap.add_argument("--gpu-variants", action="store_true",
                    help="run every lit variant on the GPU too (default: only the default lit)")
    ap.add_argument("--only", nargs="*", help="method ids or modes to run (e.g. lit lit-lr32 scatter)")
    ap.add_argument("--machine", default=None, help="one line describing the machine, for the table")
    ap.add_argument("--chart-only", metavar="OUT",
                    help="render nothing: rebuild OUT/results.md and OUT/chart_{cpu,gpu}.svg from an "
                    "existing OUT/results.json (every other option is ignored)")
    args = ap.parse_args()

    if args.chart_only:
        with open(os.path.join(args.chart_only, "results.json")) as f:
            res = json.load(f)
        with open(os.path.join(args.chart_only, "results.md"), "w") as f:
            f.write(markdown(res))
        charts = write_charts(res, args.chart_only)
        print(f"wrote {os.path.join(args.chart_only, 'results.md')}"
              + (f"; charts: {', '.join(os.path.basename(c) for c in charts)}" if charts else ""))
        return
    missing = [o for o in ("bin", "asset", "out") if not getattr(args, o)]
    if missing:
        ap.error("the following arguments are required: " + ", ".join("--" + m for m in missing))

    args.bin = os.path.abspath(args.bin)
    args.refs = {}
    for r in args.ref:
        if "=" not in r:
            ap.error(f"--ref wants SCENE=PFM, got {r!r}")
        k, v = r.split("=", 1)
        args.refs[k] = v
    os.makedirs(os.path.join(args.out, "pfm"), exist_ok=True)
    version = subprocess.run([args.bin, "--version"], capture_output=True, text=True).stdout.strip()
    methods = method_list(args)
    res = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": args.machine or f"{platform.node()}, {os.cpu_count()} CPUs",
        "bin": args.bin, "bin_version": version, "width": args.width, "height": args.height,
        "runs": args.runs, "repeat_under": args.repeat_under, "threshold": args.threshold,
        "scenes": [], "rows": [],
    }
    for asset in args.asset:
        scene = scene_name(asset)
        ref, note = find_ref(args, scene, asset)
        if ref is not None:
            h, w = read_pfm(ref).shape[:2]
            if (w, h) != (args.width, args.height):
                sys.exit(f"{ref} is {w}x{h}, the sweep renders {args.width}x{args.height}")
        sc = {"scene": scene, "asset": asset, "ref": ref, "note": note}
        res["scenes"].append(sc)
        # Runs are interleaved: round 1 runs every method once, later rounds only the fast ones,
        # so load that comes and goes (a shared machine) lands on all methods alike.
        runs = {}
        for rnd in range(args.runs):
            for m in methods:
                mid, mode, backend, extra = m[:4]
                key = (mid, backend)
                if rnd > 0 and (key not in runs or runs[key][0]["render_seconds"] >= args.repeat_under):
                    continue
                out_pfm = os.path.join(args.out, "pfm", f"{scene}_{mid}_{backend}.pfm")
                try:
                    cmd, r = render(args, asset, out_pfm, mode, backend, extra)
                except RuntimeError as e:
                    print(f"[{scene}] {mid} {backend}: FAILED\n{e}", file=sys.stderr, flush=True)
                    continue
                r["command"] = cmd
                runs.setdefault(key, []).append(r)
                print(f"[{scene}] round {rnd + 1} {mid:12s} {backend}  {r['render_seconds']:.3f} s"
                      + (f"  gpu {r['gpu_ms']:.2f} ms" if r["gpu_ms"] is not None else "")
                      + f"  (load {r['load1']:.2f})", flush=True)
        for mid, mode, backend, extra, settings, cmp in methods:
            out_pfm = os.path.join(args.out, "pfm", f"{scene}_{mid}_{backend}.pfm")
            rr = runs.get((mid, backend))
            if not rr:
                res["rows"].append({"scene": scene, "method": mid, "backend": backend,
                                    "settings": settings, "error": "render failed",
                                    "render_seconds": None, "gpu_ms": None, "runs": []})
                continue
            row = {"scene": scene, "method": mid, "mode": mode, "backend": backend,
                   "settings": settings, "command": rr[0]["command"], "image": out_pfm,
                   "render_seconds": median(r["render_seconds"] for r in rr),
                   "gpu_ms": median(r["gpu_ms"] for r in rr), "runs": rr,
                   "compare": compare(out_pfm, ref, args.threshold) if (cmp and ref) else None}
            res["rows"].append(row)
            c = row["compare"] or {}
            print(f"[{scene}] {mid:12s} {backend}  {row['render_seconds']:.3f} s"
                  + (f"  gpu {row['gpu_ms']:.2f} ms" if row["gpu_ms"] is not None else "")
                  + (f"  rel {c['rel_rmse']:.3f}  ratio {c['mean_ratio']:.3f}" if c else "")
                  + f"  (x{len(rr)})", flush=True)
        checks = [r for r in res["rows"] if r["scene"] == scene and r.get("mode") == "reference"
                  and r.get("compare")]
        if checks:
            top = max(checks, key=lambda r: int(r["method"].split("-")[1]))
            ratio = top["compare"]["mean_ratio"]
            ok = abs(ratio - 1) <= args.ref_tol
            sc["ref_check"] = (f"{top['method']} mean ratio {ratio:.4f} "
                               + ("(matches)" if ok else f"(OFF by more than {args.ref_tol}: do not trust)"))
            sc["ref_ok"] = ok
            if not ok:
                print(f"[{scene}] WARNING: reference check failed: {sc['ref_check']}", file=sys.stderr)
        with open(os.path.join(args.out, "results.json"), "w") as f:
            json.dump(res, f, indent=1)
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write(markdown(res))
    charts = write_charts(res, args.out)
    print(f"wrote {os.path.join(args.out, 'results.json')} and results.md"
          + (f"; charts: {', '.join(os.path.basename(c) for c in charts)}" if charts else ""))


if __name__ == "__main__":
    main()
