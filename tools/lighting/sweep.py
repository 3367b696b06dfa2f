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
table), pfm/ (one image per row), refs/ (references rendered with --ref-spp).

Example (the three scenes of the lit-mode tuning, converged references made beforehand):

  python3 tools/lighting/sweep.py --bin target/release/vdbcook \\
      --asset /tmp/lit/wdas.vdbc --asset /tmp/lit/storm.vdbc --asset /tmp/lit/smoke.vdbc \\
      --ref-pattern '/tmp/lit/r/{scene}_ref3.pfm' --out /tmp/lit/sweep

Needs Python 3 and numpy (for ../mitsuba/pfm.py and compare.py). Does not build anything.
"""
import argparse
import datetime
import json
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

LIT_DEFAULT = "light-res 64, 4 oct, ms 0.9,0.6,0.1, step 1"

# (id, mode, extra CLI args, settings shown in the table, compared with the reference?)
LIT_METHODS = [
    ("lit", "lit", [], LIT_DEFAULT, True),
    ("lit-ss", "lit", ["--ms-octaves", "1", "--ms-sky", "16"],
     "--ms-octaves 1 --ms-sky 16 (about single scattering)", True),
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
        backends = ["cpu"] + (gpu if (mid == "lit" or args.gpu_variants) else [])
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
    cmd = [args.bin, "render", asset, "--mode", mode, "--backend", backend,
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


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True, help="the vdbcook binary (copy it if it may be rebuilt meanwhile)")
    ap.add_argument("--asset", action="append", required=True,
                    help="a cooked asset (.vdbc); repeat for more scenes. Scene name = file stem")
    ap.add_argument("--ref", action="append", default=[], metavar="SCENE=PFM",
                    help="the converged reference of a scene (linear PFM, same camera/size/settings)")
    ap.add_argument("--ref-pattern", help="reference path with {scene}, e.g. '/refs/{scene}_ref.pfm'")
    ap.add_argument("--ref-spp", type=int, help="render a missing reference at this many spp (seed 1)")
    ap.add_argument("--out", required=True, help="output folder (results.json, results.md, pfm/)")
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
    args = ap.parse_args()

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
    print(f"wrote {os.path.join(args.out, 'results.json')} and results.md")


if __name__ == "__main__":
    main()
