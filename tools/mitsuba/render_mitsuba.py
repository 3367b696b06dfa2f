#!/usr/bin/env python3
"""Render a VDB fog volume with Mitsuba 3 under vdbcook's camera/medium/light contract.

    /tmp/mi-venv/bin/python tools/mitsuba/render_mitsuba.py SCENE.json -o OUT.pfm \
        [--variant scalar_rgb|llvm_ad_rgb] [--seed N] [--spp N] [--passes N] \
        [--rays sensor|centres] [--cache DIR] [--stderr-out ERR.pfm]

The scene JSON schema is in README.md. The output is a linear PFM (`PF`, little-endian, rows
bottom to top) of Mitsuba's radiance; a JSON line with timings and the noise estimate goes to
stdout.

Grid data: if this Python can `import pyopenvdb` the grid is read in-process, otherwise
`/usr/bin/python3 dump_grid.py` (Debian's python3-openvdb) dumps it to a cache (.npy + .json,
keyed by the VDB's path, size, mtime and the grid name).

--rays sensor   (default) Mitsuba's own `perspective` sensor + `hdrfilm` (box filter): each pixel
                is the average over its area. Mitsuba's look_at+perspective turned out not to
                mirror anything (see README), so the image is written as Mitsuba produces it.
--rays centres  (llvm_ad_rgb only) rays built from vdbcook's camera contract, one direction
                per pixel through its centre, fed to the volpath integrator directly
                (`integrator.sample`): the same rays vdbcook traces, so no pixel-area filtering
                difference.

The spp are split into --passes passes with different seeds (default: enough passes that one
pass has at most ~4 M paths, and at least 4); the per-pixel standard error of the mean is
estimated from the spread of the pass means.
"""
import argparse
import hashlib
import json
import math
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from pfm import write_pfm  # noqa: E402

SYSTEM_PYTHON = "/usr/bin/python3"


def load_grid(vdb_path, grid, cache_dir):
    """(zyx float32 array, meta dict) of the dense dump of the grid."""
    vdb_path = os.path.abspath(vdb_path)
    try:
        import pyopenvdb  # noqa: F401
        in_process = True
    except ImportError:
        in_process = False
    st = os.stat(vdb_path)
    key = hashlib.sha1(f"{vdb_path}|{st.st_size}|{st.st_mtime_ns}|{grid}".encode()).hexdigest()[:16]
    os.makedirs(cache_dir, exist_ok=True)
    prefix = os.path.join(cache_dir, f"{os.path.basename(vdb_path)}.{grid}.{key}")
    if not (os.path.exists(prefix + ".npy") and os.path.exists(prefix + ".json")):
        if in_process:
            import dump_grid
            dump_grid.dump(vdb_path, grid, prefix)
        else:
            r = subprocess.run([SYSTEM_PYTHON, os.path.join(HERE, "dump_grid.py"), vdb_path, grid,
                                prefix], capture_output=True, text=True)
            if r.returncode != 0:
                sys.exit(f"dump_grid failed:\n{r.stderr}{r.stdout}")
            if r.stderr:
                sys.stderr.write(r.stderr)
    with open(prefix + ".json") as f:
        meta = json.load(f)
    return np.load(prefix + ".npy"), meta


def normalize(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def build_scene(mi, sc, data, meta):
    T = mi.ScalarTransform4f
    lo = np.array(meta["lo"], dtype=np.float64)
    hi = np.array(meta["hi"], dtype=np.float64)
    s = np.array(meta["voxel_scale"], dtype=np.float64)
    t = np.array(meta["translate"], dtype=np.float64)
    # Index box of the dense block: [lo - 1/2, hi + 1/2]; world = s * index + t.
    wmin = s * (lo - 0.5) + t
    wmax = s * (hi + 0.5) + t
    size = wmax - wmin
    # gridvolume: unit cube [0,1]^3 -> world box (voxel centres at (i + 1/2)/res -> s*(lo+i)+t).
    vol_to_world = T().translate(wmin.tolist()).scale(size.tolist())
    # cube shape: [-1,1]^3 -> world box.
    cube_to_world = T().translate(((wmin + wmax) / 2).tolist()).scale((size / 2).tolist())

    tensor = mi.TensorXf(np.ascontiguousarray(data[..., None], dtype=np.float32))
    medium = {
        "type": "heterogeneous",
        "sigma_t": {
            "type": "gridvolume",
            "data": tensor,
            "filter_type": "nearest",
            "to_world": vol_to_world,
        },
        "albedo": float(sc["albedo"]),
        "scale": float(sc["extinction"]),
        "phase": {"type": "hg", "g": float(sc.get("phase_g", 0.0))},
    }
    cam = sc["camera"]
    eye, look, up = (np.array(cam[k], dtype=np.float64) for k in ("eye", "look", "up"))
    dist = float(np.linalg.norm(look - eye))
    scene = {
        "type": "scene",
        "integrator": {
            "type": "volpath",
            "max_depth": int(sc["max_depth"]),
            "hide_emitters": bool(sc.get("hide_emitters", False)),
        },
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": float(cam["fov_y_deg"]),
            "near_clip": 1e-4 * dist,
            "far_clip": 1e4 * (dist + float(np.linalg.norm(size))),
            "to_world": T().look_at(origin=eye.tolist(), target=look.tolist(), up=up.tolist()),
            "film": {
                "type": "hdrfilm",
                "width": int(sc["width"]),
                "height": int(sc["height"]),
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
                "component_format": "float32",
            },
            "sampler": {"type": "independent", "sample_count": int(sc["spp"])},
        },
        "volume": {
            "type": "cube",
            "to_world": cube_to_world,
            "bsdf": {"type": "null"},
            "interior": medium,
        },
    }
    sun = sc.get("sun")
    if sun:
        scene["sun"] = {
            "type": "directional",
            "direction": (-normalize(sun["dir"])).tolist(),
            "irradiance": {"type": "rgb", "value": [float(v) for v in sun["irradiance"]]},
        }
    sky = sc.get("sky")
    if sky:
        scene["sky"] = {"type": "constant",
                        "radiance": {"type": "rgb", "value": [float(v) for v in sky]}}
    return scene, (wmin, wmax)


def camera_basis(sc):
    """vdbcook's pinhole basis from the scene JSON: eye, forward f, right r, up u (unit), the
    tangent of half the vertical field of view, and the image size."""
    cam = sc["camera"]
    W, H = int(sc["width"]), int(sc["height"])
    eye, look, up = (np.array(cam[k], dtype=np.float64) for k in ("eye", "look", "up"))
    f = normalize(look - eye)
    r = normalize(np.cross(f, up))
    u = np.cross(r, f)
    th = math.tan(math.radians(float(cam["fov_y_deg"])) / 2)
    return eye, f, r, u, th, W, H


def centre_rays(mi, dr, sc, spp):
    """vdbcook's camera contract: pixel (i, j), row 0 at the top, spp copies of each ray
    (lane = pixel * spp + sample), directions computed in float64."""
    eye, f, r, u, th, W, H = camera_basis(sc)
    F64 = dr.float64_array_t(mi.Float)
    U32 = mi.UInt32
    pix = dr.arange(U32, W * H * spp) // spp
    i = F64(pix % W)
    j = F64(pix // W)
    sx = (2 * (i + 0.5) / W - 1) * (th * W / H)
    sy = (1 - 2 * (j + 0.5) / H) * th
    d = [float(f[a]) + sx * float(r[a]) + sy * float(u[a]) for a in range(3)]
    inv = dr.rsqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    return mi.RayDifferential3f(o=mi.Point3f(*[float(v) for v in eye]),
                                d=mi.Vector3f(*[mi.Float(c * inv) for c in d]))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--spp", type=int, help="override the scene's spp")
    ap.add_argument("--passes", type=int, help="split spp into this many passes (>= 2 for a noise estimate)")
    ap.add_argument("--rays", choices=("sensor", "centres"), default="sensor")
    ap.add_argument("--cache", default="/tmp/vdbcook-mitsuba-cache")
    ap.add_argument("--stderr-out", help="also write the per-pixel standard error of the mean (PFM)")
    args = ap.parse_args()

    with open(args.scene) as fh:
        sc = json.load(fh)
    base = os.path.dirname(os.path.abspath(args.scene))
    vdb_path = sc["vdb"] if os.path.isabs(sc["vdb"]) else os.path.join(base, sc["vdb"])
    spp = int(args.spp or sc["spp"])
    W, H = int(sc["width"]), int(sc["height"])

    t0 = time.perf_counter()
    data, meta = load_grid(vdb_path, sc["grid"], args.cache)
    t_load = time.perf_counter() - t0

    import mitsuba as mi
    mi.set_variant(args.variant)
    import drjit as dr

    if args.rays == "centres" and not args.variant.startswith(("llvm", "cuda")):
        sys.exit("--rays centres needs a vectorised variant (llvm_ad_rgb)")

    t0 = time.perf_counter()
    scene_dict, (wmin, wmax) = build_scene(mi, sc, data, meta)
    scene = mi.load_dict(scene_dict)
    t_build = time.perf_counter() - t0

    max_paths = 1 << 22
    passes = args.passes or max(4, math.ceil(W * H * spp / max_paths))
    passes = max(1, min(passes, spp))
    per = [spp // passes + (1 if k < spp % passes else 0) for k in range(passes)]

    acc = np.zeros((H, W, 3), dtype=np.float64)
    acc2 = np.zeros((H, W, 3), dtype=np.float64)
    t0 = time.perf_counter()
    integrator = scene.integrator()
    for k, n in enumerate(per):
        seed = args.seed * 100003 + k
        if args.rays == "sensor":
            img = np.array(mi.render(scene, spp=n, seed=seed), dtype=np.float64)[:, :, :3]
        else:
            ray = centre_rays(mi, dr, sc, n)
            sampler = mi.load_dict({"type": "independent", "sample_count": n})
            sampler.seed(seed, W * H * n)
            L, _, _ = integrator.sample(scene, sampler, ray, None, True)
            L = np.array(L, dtype=np.float64)  # [3, W*H*n]; evaluates all channels in one kernel
            img = L.reshape(3, H, W, n).mean(axis=3).transpose(1, 2, 0)
        acc += img * n
        acc2 += img * img * n
    t_render = time.perf_counter() - t0
    mean = acc / spp
    # Weighted spread of the pass means -> standard error of the overall mean.
    if passes >= 2:
        var_pass = np.maximum(acc2 / spp - mean * mean, 0.0)  # ~ var(sample) / n_pass
        stderr = np.sqrt(var_pass / max(passes - 1, 1))
    else:
        stderr = np.full_like(mean, np.nan)
    write_pfm(args.output, mean)
    if args.stderr_out:
        write_pfm(args.stderr_out, stderr)
    lum = mean.mean(axis=2)
    print(json.dumps({
        "output": args.output, "variant": args.variant, "rays": args.rays,
        "width": W, "height": H, "spp": spp, "passes": passes, "seed": args.seed,
        "grid_shape_zyx": meta["shape_zyx"], "world_box": [wmin.tolist(), wmax.tolist()],
        "load_seconds": round(t_load, 3), "build_seconds": round(t_build, 3),
        "render_seconds": round(t_render, 3),
        "mean": mean.mean(axis=(0, 1)).tolist(),
        "stderr_rms": float(np.sqrt(np.nanmean(stderr ** 2))) if passes >= 2 else None,
        "max": float(lum.max()),
    }))


if __name__ == "__main__":
    main()
