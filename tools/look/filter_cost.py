"""The cost of `--filter trilinear` against `--filter nearest` in the lit mode, and how much of
the image it changes (docs/rendering.md, "Voxel cubes"): three real volumes at the default
framing and a close-up, CPU and GPU backends, the median of three renders each.

Run: python3 tools/look/filter_cost.py [SAMPLES_DIR] [BLENDER_FIRE.vdb]
(defaults ../shared/samples and /tmp/fire/blender/fireload_90784781/fluid_data_0060.vdb, a
Blender Mantaflow frame from InteractiveSimulations/Fireload; not committed). Needs a release
build (`cargo build --release -p vdbcook`). Prints a Markdown table.
"""
import json, subprocess, sys, struct, math, os
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
V = os.path.join(ROOT, "target", "release", "vdbcook")
S = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "..", "shared", "samples")
FIRE = sys.argv[2] if len(sys.argv) > 2 else "/tmp/fire/blender/fireload_90784781/fluid_data_0060.vdb"
TMP = "/tmp/vdbcook-filter-cost"
os.makedirs(TMP, exist_ok=True)
os.makedirs("/tmp/xdg", mode=0o700, exist_ok=True)
files = [("openvdb smoke (Houdini)", f"{S}/openvdb-smoke1/smoke.vdb", []),
         ("WDAS cloud", f"{S}/wdas-cloud/wdas_cloud_sixteenth.vdb", []),
         ("Blender fire (Mantaflow)", FIRE, [])]
def pfm(p):
    b = open(p, "rb").read()
    parts = b.split(b"\n", 3)
    w, h = map(int, parts[1].split()); data = parts[3]
    return struct.unpack(f"<{w*h*3}f", data[:w*h*12])
def run(args):
    out = subprocess.run([V] + args + ["--json"], capture_output=True, text=True, env=dict(os.environ, XDG_RUNTIME_DIR="/tmp/xdg"))
    if out.returncode: print(out.stderr); sys.exit(1)
    return json.loads(out.stdout)
rows = []
for name, f, extra in files:
    d = run(["render", f, "-o", f"{TMP}/probe.png", "--mode", "lit", "--width", "64", "--height", "36", "--backend", "cpu"] + extra)
    c = d["camera"]; e, l = c["eye"], c["look_at"]
    for zoom, label in [(1.0, "default framing"), (0.3, "close-up (0.3× distance)")]:
        eye = [l[i] + zoom * (e[i] - l[i]) for i in range(3)]
        cam = ",".join(str(x) for x in eye + l + [c["fov_y_deg"]])
        res = {}
        for backend in ["cpu", "gpu"]:
            for filt in ["nearest", "trilinear"]:
                ts = []
                for k in range(3):
                    out = f"{TMP}/{filt}-{backend}.pfm"
                    j = run(["render", f, "-o", out, "--mode", "lit", "--width", "640", "--height", "360", "--camera", cam, "--backend", backend, "--filter", filt, "--march", "steps"] + extra)
                    ts.append(j["gpu_ms"] / 1e3 if backend == "gpu" and j["gpu_ms"] else j["render_seconds"])
                res[(backend, filt)] = (sorted(ts)[1], pfm(out), j["settings"]["filter"])
        a, b = res[("cpu", "nearest")][1], res[("cpu", "trilinear")][1]
        num = sum((x - y) ** 2 for x, y in zip(a, b)); den = sum(y * y for y in b)
        auto = run(["render", f, "-o", f"{TMP}/auto.png", "--mode", "lit", "--width", "640", "--height", "360", "--camera", cam, "--backend", "cpu"] + extra)["settings"]["filter"]
        rows.append((name, label, res[("cpu","nearest")][0], res[("cpu","trilinear")][0], res[("gpu","nearest")][0], res[("gpu","trilinear")][0], math.sqrt(num / den), auto))
print("| volume | view | CPU nearest s | CPU trilinear s | lavapipe nearest s | lavapipe trilinear s | nearest vs trilinear rel. RMSE | --filter auto takes |")
print("|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r[0]} | {r[1]} | {r[2]:.2f} | {r[3]:.2f} | {r[4]:.2f} | {r[5]:.2f} | {100*r[6]:.1f}% | {r[7]} |")
