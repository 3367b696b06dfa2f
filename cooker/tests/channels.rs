//! Multi-channel assets (`cook --grids`) end to end through the binary, against OpenVDB's own
//! truth files (written by python3-openvdb with the fire fixtures) and against `eval`, whose
//! reader is itself checked against OpenVDB: lossless cooks are exact per grid, per-channel
//! `--max-error` holds on every voxel, output is deterministic, channel 0 renders exactly as a
//! single-grid asset of the same grid, and bad inputs get clear refusals.

mod common;

use std::path::Path;

use common::{gpu_required, json, read_pfm, root, vdbcook as run};
use serde_json::Value;

const FIRE: &str = "fixtures/seq/fire";
const GRIDS: [&str; 3] = ["density", "temperature", "flame"];

/// OpenVDB's truth of grid `name` in `fixtures/seq/fire/fire.000N.truth.json`.
fn fire_truth(frame: usize, name: &str) -> Value {
    let p = root().join(format!("{FIRE}/fire.{:04}.truth.json", frame + 1));
    let t: Value = serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    t["grids"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["name"] == name)
        .unwrap()
        .clone()
}

fn cook(out: &Path, extra: &[&str]) -> Value {
    let o = out.to_str().unwrap();
    let mut args = vec![
        "cook",
        "--json",
        FIRE,
        "-o",
        o,
        "--grids",
        "density,temperature,flame",
    ];
    args.extend_from_slice(extra);
    json(&args)
}

/// Cooks grid `grid` of the fire alone (a single-grid asset).
fn cook_one(out: &Path, grid: &str) {
    let (code, _, err) = run(&["cook", FIRE, "--grid", grid, "-o", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
}

#[test]
fn lossless_fire_channels_are_exact_per_grid_against_openvdb_truth() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("fire.vdbc");
    let c = cook(&out, &[]);
    let o = out.to_str().unwrap();
    let info = json(&["info", "--json", o]);
    assert_eq!(info["format_version"], 3);
    let e = json(&["eval", "--json", o, FIRE]);
    assert_eq!(e["max_abs"], 0.0, "{e}");
    assert_eq!(e["inactive_errors"], 0);
    let mut total = 0;
    for (ci, name) in GRIDS.iter().enumerate() {
        let ch = &info["channels"][ci];
        assert_eq!(ch["name"], *name);
        let ev = &e["channels"][ci];
        assert_eq!(ev["name"], *name);
        assert_eq!(ev["exact"], true, "{name}");
        let mut sum = 0;
        for f in 0..4 {
            let t = fire_truth(f, name);
            let n = t["active_voxels"].as_u64().unwrap();
            assert_eq!(ch["frames"][f]["active_voxels"], n, "{name} frame {f}");
            sum += n;
            // The stored box covers OpenVDB's active box (at leaf granularity), per channel.
            if n > 0 {
                for a in 0..3 {
                    let lo = ch["frames"][f]["bbox_min"][a].as_i64().unwrap();
                    let hi = ch["frames"][f]["bbox_max"][a].as_i64().unwrap();
                    assert!(lo <= t["bbox_min"][a].as_i64().unwrap(), "{name} {f}");
                    assert!(hi >= t["bbox_max"][a].as_i64().unwrap(), "{name} {f}");
                    assert!(hi - t["bbox_max"][a].as_i64().unwrap() < 8, "{name} {f}");
                }
            } else {
                // Flame burnt out in frame 4: the channel stores nothing there.
                assert!(ch["frames"][f]["bbox_min"].is_null(), "{name} {f}");
                assert_eq!(ch["frames"][f]["bricks"], 0);
            }
        }
        assert_eq!(ch["active_voxels"], sum, "{name}");
        assert_eq!(ev["active_voxels"], sum, "{name}");
        assert_eq!(c["channels"][ci]["active_voxels"], sum, "{name}");
        total += sum;
    }
    assert_eq!(c["active_voxels"], total);
    assert_eq!(e["active_voxels"], total);
    // One shared topology: fewer L2 nodes than three single-grid cooks together.
    let mut nodes = 0;
    for name in GRIDS {
        let p = d.path().join(format!("{name}.vdbc"));
        let s = json(&[
            "cook",
            "--json",
            FIRE,
            "--grid",
            name,
            "-o",
            p.to_str().unwrap(),
        ]);
        nodes += s["nodes"]["l2"].as_u64().unwrap();
        // The single-grid asset stays version 2.
        assert_eq!(
            json(&["info", "--json", p.to_str().unwrap()])["format_version"],
            2
        );
    }
    assert!(c["nodes"]["l2"].as_u64().unwrap() < nodes);
}

#[test]
fn per_channel_max_error_holds_on_every_voxel_and_eval_agrees() {
    let d = tempfile::tempdir().unwrap();
    let budgets = [0.01, 5.0, 0.02];
    for (k, spec) in [
        "density=0.01,temperature=5,flame=0.02",
        // A bare budget for the channels not named.
        "0.01,temperature=5,flame=0.02",
    ]
    .iter()
    .enumerate()
    {
        let out = d.path().join(format!("fire{k}.vdbc"));
        let c = cook(&out, &["--format", "bc4", "--max-error", spec]);
        let e = json(&["eval", "--json", out.to_str().unwrap(), FIRE]);
        for (ci, name) in GRIDS.iter().enumerate() {
            let cc = &c["channels"][ci];
            let ec = &e["channels"][ci];
            assert_eq!(cc["max_error"].as_f64().unwrap() as f32, budgets[ci] as f32);
            let any_gpu = cc["error"]["max_abs_any_gpu"].as_f64().unwrap();
            let measured = ec["max_abs"].as_f64().unwrap();
            assert!(any_gpu <= budgets[ci], "{spec} {name}: {any_gpu}");
            assert!(measured <= budgets[ci], "{spec} {name}: {measured}");
            assert!(
                (measured - cc["error"]["max_abs"].as_f64().unwrap()).abs() < 1e-9,
                "{name}: cook and eval disagree"
            );
            // Not lossless: the budget was used (each channel is lossy somewhere).
            assert!(measured > 0.0, "{spec} {name}");
        }
        // Each channel is held to its own budget, not to the smallest one: temperature's error
        // is over density's budget (a global minimum would store it far more finely).
        assert!(e["channels"][1]["max_abs"].as_f64().unwrap() > budgets[0] * 10.0);
        // A temperature budget in Kelvin does not loosen density: its error stays in its own
        // units, 500× below temperature's.
        assert!(
            e["channels"][0]["max_abs"].as_f64().unwrap()
                < e["channels"][1]["max_abs"].as_f64().unwrap() / 100.0
        );
    }
    // The same cook at 1 and 2 threads: the same bytes.
    let a = d.path().join("t1.vdbc");
    let b = d.path().join("t2.vdbc");
    for (t, p) in [("1", &a), ("2", &b)] {
        let (code, _, err) = run(&[
            "--threads",
            t,
            "cook",
            FIRE,
            "--grids",
            "density,temperature,flame",
            "--format",
            "bc4",
            "--max-error",
            "density=0.01,temperature=5,flame=0.02",
            "-o",
            p.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
    }
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn grids_with_different_active_regions_share_one_topology_exactly() {
    // multi_grids.vdb: `density` and the DoubleGrid `heat_d` share a transform but not their
    // active regions (truth: 1,370 and 578 voxels).
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("m.vdbc");
    let o = out.to_str().unwrap();
    let input = "fixtures/vdb/multi_grids.vdb";
    let c = json(&[
        "cook",
        "--json",
        input,
        "--grids",
        "density,heat_d",
        "-o",
        o,
    ]);
    assert_eq!(c["channels"][0]["active_voxels"], 1370);
    assert_eq!(c["channels"][1]["active_voxels"], 578);
    let e = json(&["eval", "--json", o, input]);
    assert_eq!(e["max_abs"], 0.0);
    assert_eq!(e["channels"][1]["active_voxels"], 578);
    // `--grid` limits eval to one channel.
    let one = json(&["eval", "--json", o, input, "--grid", "heat_d"]);
    assert_eq!(one["active_voxels"], 578);
    assert_eq!(one["channels"].as_array().unwrap().len(), 1);
}

fn refused(args: &[&str], out: &Path, needles: &[&str]) {
    let (code, _, err) = run(args);
    assert_ne!(code, 0, "{args:?} accepted");
    for n in needles {
        assert!(err.contains(n), "{args:?}: '{n}' missing from: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "{args:?} left {}", out.display());
}

#[test]
fn bad_channel_inputs_are_refused_clearly_and_leave_no_output() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("x.vdbc");
    let o = out.to_str().unwrap();
    // Different voxel sizes: no silent resampling.
    refused(
        &[
            "cook",
            "fixtures/vdb/fire_mixed_xform.vdb",
            "--grids",
            "density,temperature",
            "-o",
            o,
        ],
        &out,
        &["different transforms", "temperature", "density"],
    );
    // A non-float grid asked as a channel.
    refused(
        &[
            "cook",
            "fixtures/vdb/fire_vec.vdb",
            "--grids",
            "density,vel",
            "-o",
            o,
        ],
        &out,
        &["vel"],
    );
    // A grid no frame has.
    refused(
        &["cook", FIRE, "--grids", "density,soot", "-o", o],
        &out,
        &["soot"],
    );
    // Budgets for grids not cooked, duplicates, an option several grids cannot share.
    refused(
        &[
            "cook",
            FIRE,
            "--grids",
            "density,flame",
            "--max-error",
            "heat=3",
            "-o",
            o,
        ],
        &out,
        &["heat", "not a cooked grid"],
    );
    refused(
        &["cook", FIRE, "--grids", "density,density", "-o", o],
        &out,
        &["twice"],
    );
    refused(
        &[
            "cook",
            FIRE,
            "--grids",
            "density,flame",
            "--range",
            "global",
            "-o",
            o,
        ],
        &out,
        &["--range global", "several grids"],
    );
    refused(
        &[
            "cook",
            FIRE,
            "--grids",
            "density,flame",
            "--grid",
            "density",
            "-o",
            o,
        ],
        &out,
        &["cannot be used with"],
    );
    refused(
        &[
            "cook",
            FIRE,
            "--grids",
            "density,flame",
            "--max-error",
            "flame=x",
            "-o",
            o,
        ],
        &out,
        &["not a number"],
    );
}

#[test]
fn a_grid_missing_in_some_frames_is_an_error_or_background_when_allowed() {
    // Frames 1-2 of the fire plus a third frame with only `density` (and a vector grid), on the
    // same transform.
    let d = tempfile::tempdir().unwrap();
    let seq = d.path().join("seq");
    std::fs::create_dir(&seq).unwrap();
    for (src, dst) in [
        ("fixtures/seq/fire/fire.0001.vdb", "f.0001.vdb"),
        ("fixtures/seq/fire/fire.0002.vdb", "f.0002.vdb"),
        ("fixtures/vdb/fire_vec.vdb", "f.0003.vdb"),
    ] {
        std::fs::copy(root().join(src), seq.join(dst)).unwrap();
    }
    let s = seq.to_str().unwrap();
    let out = d.path().join("m.vdbc");
    let o = out.to_str().unwrap();
    refused(
        &["cook", s, "--grids", "density,temperature", "-o", o],
        &out,
        &["f.0003.vdb", "temperature", "--allow-missing-grid"],
    );
    let c = json(&[
        "cook",
        "--json",
        s,
        "--grids",
        "density,temperature",
        "--allow-missing-grid",
        "-o",
        o,
    ]);
    assert_eq!(c["missing_grid_frames"].as_array().unwrap().len(), 1);
    let info = json(&["info", "--json", o]);
    assert_eq!(info["channels"][1]["frames"][2]["active_voxels"], 0);
    assert_eq!(info["channels"][1]["frames"][2]["bricks"], 0);
    assert_eq!(info["channels"][0]["frames"][2]["active_voxels"], 147);
    let e = json(&["eval", "--json", o, s]);
    assert_eq!(e["max_abs"], 0.0, "{e}");
}

#[test]
fn channel_zero_renders_exactly_as_the_single_grid_asset() {
    // The shared topology adds slots where only other channels live (EMPTY refs for density):
    // every mode that renders channel 0 must not see them.
    let d = tempfile::tempdir().unwrap();
    let multi = d.path().join("m.vdbc");
    let single = d.path().join("s.vdbc");
    cook(&multi, &[]);
    cook_one(&single, "density");
    for backend in ["cpu", "gpu"] {
        for mode in ["density", "scatter", "lit"] {
            let mut imgs = Vec::new();
            for (k, a) in [&multi, &single].iter().enumerate() {
                let name = format!("{backend}-{mode}-{k}");
                // Channel 0 alone: the fire's default glow off.
                let extra = ["--mode", mode, "--backend", backend, "--emission", "off"];
                let Some(img) = render_pfm(d.path(), a, &name, &extra) else {
                    return;
                };
                imgs.push(img.iter().map(|v| v.to_bits()).collect::<Vec<u32>>());
            }
            assert!(imgs[0] == imgs[1], "{backend} {mode}: the images differ");
        }
    }
}

/// Renders `asset` to a PFM (64×48) with `extra` flags; `None` when the GPU backend has no
/// adapter and may skip.
fn render_pfm(dir: &Path, asset: &Path, name: &str, extra: &[&str]) -> Option<Vec<f32>> {
    let img = dir.join(format!("{name}.pfm"));
    let mut args = vec![
        "render",
        asset.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "-o",
        img.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let (code, _, err) = run(&args);
    if extra.contains(&"gpu") && code != 0 && !gpu_required() && err.contains("no GPU adapter") {
        eprintln!("skipping: {err}");
        return None;
    }
    assert_eq!(code, 0, "{args:?}: {err}");
    Some(read_pfm(&img).2)
}

/// Largest difference relative to the image's peak.
fn rel_diff(a: &[f32], b: &[f32]) -> f32 {
    let peak = a.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-12);
    a.iter()
        .zip(b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()))
        / peak
}

#[test]
fn fire_emission_reads_the_temperature_channel_behind_the_density() {
    let d = tempfile::tempdir().unwrap();
    let multi = d.path().join("fire.vdbc");
    let temp = d.path().join("temperature.vdbc");
    cook(&multi, &[]);
    cook_one(&temp, "temperature");
    // The camera frames what channel 0 stores: give both renders the same one.
    let cam = ["--camera", "3,1.2,3,0,0.7,0,40"];
    let glow = ["--emission", "600,1800", "--emission-intensity", "2"];
    for backend in ["cpu", "gpu"] {
        let r = |asset: &Path, name: &str, absorb: &str, glowing: bool| {
            let mut args = vec![
                "--backend",
                backend,
                "--mode",
                "density",
                "--absorb",
                absorb,
            ];
            args.extend_from_slice(&cam);
            if glowing {
                args.extend_from_slice(&glow);
            }
            render_pfm(d.path(), asset, &format!("{backend}-{name}"), &args)
        };
        // Without absorption the density does not matter: the emission of the temperature
        // channel equals the single-grid emission of the temperature grid (the tested path
        // that reads the rendered grid's own values), the line integral of E.
        let Some(a) = r(&multi, "m", "0", true) else {
            return;
        };
        let t = r(&temp, "t", "0", true).unwrap();
        let peak = a.iter().fold(0.0f32, |m, v| m.max(*v));
        assert!(peak > 0.1, "{backend}: no glow");
        assert!(rel_diff(&t, &a) < 1e-4, "{backend}: {}", rel_diff(&t, &a));
        // Pixels that miss the hot channel stay black.
        let dark = a.chunks(3).filter(|p| p.iter().all(|&v| v == 0.0)).count();
        assert!(dark > a.len() / 3 / 4, "{backend}: {dark} black pixels");
        // Smoke in front absorbs: rgb = (1 − T) + emission, so the emission is the difference
        // to the render without it; no pixel gains, and the image is dimmer.
        let s = r(&multi, "s", "2", true).unwrap();
        let grey = r(&multi, "g", "2", false).unwrap();
        let (mut sum_free, mut sum_abs) = (0.0f64, 0.0f64);
        for ((x, y), z) in s.iter().zip(&grey).zip(&a) {
            let e = x - y;
            assert!(
                e <= z + 1e-4 * peak,
                "{backend}: absorption brightened a pixel"
            );
            sum_abs += e as f64;
            sum_free += *z as f64;
        }
        assert!(
            sum_abs < 0.95 * sum_free,
            "{backend}: {sum_abs} vs {sum_free}"
        );
    }
}

#[test]
fn fire_emission_agrees_between_cpu_and_gpu_in_every_mode_that_draws_it() {
    let d = tempfile::tempdir().unwrap();
    let multi = d.path().join("fire.vdbc");
    cook(&multi, &[]);
    // The trilinear filter reads another channel's emission trilinearly (no voxel cubes): the
    // same on both backends.
    for (mode, filter) in [
        ("density", "nearest"),
        ("scatter", "nearest"),
        ("lit", "nearest"),
        ("density", "trilinear"),
        ("lit", "trilinear"),
    ] {
        let mut imgs = Vec::new();
        for backend in ["cpu", "gpu"] {
            let extra = [
                "--mode",
                mode,
                "--backend",
                backend,
                "--emission",
                "600,1800",
                "--filter",
                filter,
            ];
            let name = format!("{mode}-{filter}-{backend}");
            match render_pfm(d.path(), &multi, &name, &extra) {
                Some(i) => imgs.push(i),
                None => return,
            }
        }
        // f32 against f64 over a few hundred voxels: within 1e-4 of the peak.
        assert!(
            rel_diff(&imgs[0], &imgs[1]) < 1e-4,
            "{mode} {filter}: {}",
            rel_diff(&imgs[0], &imgs[1])
        );
    }
    // multi_grids.vdb: a hot `heat_d` (1000–1004 K) and a separate `density` blob, seen through
    // the blob: the smoke in front of the emission's box absorbs it (the march's prefix).
    let mg = d.path().join("mg.vdbc");
    let input = "fixtures/vdb/multi_grids.vdb";
    let (code, _, err) = run(&[
        "cook",
        input,
        "--grids",
        "density,heat_d",
        "-o",
        mg.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let view = |backend: &'static str, absorb: &'static str, glow: bool| {
        let mut a = vec![
            "--mode",
            "density",
            "--backend",
            backend,
            "--absorb",
            absorb,
        ];
        a.extend(["--camera", "19.4,24.75,21.1,3.75,1,4.25,40"]);
        if glow {
            a.extend(["--emission", "999,1005", "--emission-grid", "heat_d"]);
        }
        a
    };
    let mut emitted = Vec::new();
    for backend in ["cpu", "gpu"] {
        let mut e = Vec::new();
        for absorb in ["0", "1"] {
            let name = format!("mg-{backend}-{absorb}");
            let Some(with) = render_pfm(d.path(), &mg, &name, &view(backend, absorb, true)) else {
                return;
            };
            let without =
                render_pfm(d.path(), &mg, &(name + "-n"), &view(backend, absorb, false)).unwrap();
            e.push(
                with.iter()
                    .zip(&without)
                    .map(|(a, b)| a - b)
                    .collect::<Vec<f32>>(),
            );
        }
        let total = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>();
        assert!(total(&e[0]) > 1.0, "{backend}: no glow");
        assert!(
            total(&e[1]) < 0.9 * total(&e[0]),
            "{backend}: the smoke in front absorbs nothing"
        );
        emitted.push(e);
    }
    for (k, (c, g)) in emitted[0].iter().zip(&emitted[1]).enumerate() {
        let r = rel_diff(c, g);
        assert!(r < 1e-4, "heat_d behind density, absorb {k}: cpu/gpu {r}");
    }
}

/// Per-pixel difference `a − b` (an emission term: the render with it minus without).
fn minus(a: &[f32], b: &[f32]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| (x - y) as f64).collect()
}

/// (Monte Carlo sum / exact sum, RMSE relative to the exact RMS over pixels above 5% of its
/// peak).
fn mc_error(exact: &[f64], mc: &[f64]) -> (f64, f64) {
    let peak = exact.iter().fold(0.0f64, |m, v| m.max(*v));
    let (mut e2, mut x2, mut n) = (0.0, 0.0, 0);
    for (x, m) in exact.iter().zip(mc) {
        if *x > 0.05 * peak {
            e2 += (m - x) * (m - x);
            x2 += x * x;
            n += 1;
        }
    }
    assert!(n > 50, "{n} glowing pixels");
    let sum = |v: &[f64]| v.iter().sum::<f64>();
    (sum(mc) / sum(exact), (e2 / x2).sqrt())
}

/// Delta tracking and the reference path tracer draw another channel's emission by the
/// track-length estimator (`∫ E ds` up to each flight's collision). Its mean is the exact
/// march's `∫ T E ds`: against the scatter mode's exact term (same extinction) and, with an
/// absorbing medium and no lights, the density mode's, the error falls as 1/√spp; the GPU's
/// delta tracking takes the CPU's very samples, in 64-sample dispatches (one 256-sample dispatch
/// comes back biased on lavapipe).
#[test]
fn fire_emission_from_a_channel_converges_in_delta_and_reference() {
    let d = tempfile::tempdir().unwrap();
    let multi = d.path().join("fire.vdbc");
    cook(&multi, &[]);
    let base = ["--camera", "3,1.2,3,0,0.7,0,40", "--emission", "600,1800"];
    let off = ["--camera", "3,1.2,3,0,0.7,0,40", "--emission", "off"];
    let r = |name: &str, extra: &[&str], glow: bool| {
        let mut args: Vec<&str> = extra.to_vec();
        args.extend_from_slice(if glow { &base[..] } else { &off[..] });
        render_pfm(d.path(), &multi, name, &args)
    };
    let medium = ["--absorb", "2", "--scatter", "3"];
    let with = |mode: &'static str, backend: &'static str, spp: &'static str| {
        let mut a = vec!["--mode", mode, "--backend", backend, "--spp", spp];
        a.extend_from_slice(&medium);
        a
    };
    // The exact term: the scatter mode's march with the same extinction (5).
    let exact = minus(
        &r("sw", &with("scatter", "cpu", "1"), true).unwrap(),
        &r("sn", &with("scatter", "cpu", "1"), false).unwrap(),
    );
    // Delta tracking's light does not depend on the emission (the estimator draws no random
    // numbers): the difference of two renders with one seed is its emission estimate alone.
    let mut errs = Vec::new();
    let mut cpu256 = None;
    for spp in ["64", "256"] {
        let w = r(&format!("dw{spp}"), &with("delta", "cpu", spp), true).unwrap();
        let n = r(&format!("dn{spp}"), &with("delta", "cpu", spp), false).unwrap();
        let (ratio, rmse) = mc_error(&exact, &minus(&w, &n));
        assert!(
            (ratio - 1.0).abs() < 0.02,
            "delta {spp} spp: sum ratio {ratio}"
        );
        errs.push(rmse);
        cpu256 = Some(w);
    }
    assert!(errs[1] < 0.05, "delta 256 spp: relative RMSE {}", errs[1]);
    assert!(
        errs[1] < 0.65 * errs[0],
        "delta: no 1/sqrt(spp) convergence {errs:?}"
    );
    if let Some(g) = r("gw256", &with("delta", "gpu", "256"), true) {
        let c = cpu256.unwrap();
        assert!(
            rel_diff(&c, &g) < 1e-4,
            "delta cpu/gpu {}",
            rel_diff(&c, &g)
        );
    }
    // The reference: an absorbing medium (albedo 0), no sun, no sky — its image is the emission
    // alone, against the density mode's exact term with the same absorption.
    let dark = [
        "--absorb",
        "2",
        "--scatter",
        "0",
        "--light",
        "0.3,0.3,0,0,0,0",
        "--sky",
        "0,0,0",
        "--backend",
        "cpu",
    ];
    let mut dens: Vec<&str> = dark.to_vec();
    dens.extend(["--mode", "density"]);
    let exact = minus(
        &r("xw", &dens, true).unwrap(),
        &r("xn", &dens, false).unwrap(),
    );
    let mut refr: Vec<&str> = dark.to_vec();
    refr.extend(["--mode", "reference", "--spp", "256"]);
    let img = r("rw", &refr, true).unwrap();
    let (ratio, rmse) = mc_error(&exact, &img.iter().map(|&v| v as f64).collect::<Vec<_>>());
    assert!((ratio - 1.0).abs() < 0.02, "reference: sum ratio {ratio}");
    assert!(rmse < 0.05, "reference: relative RMSE {rmse}");
}

/// A channel whose every active value lies within its budget of its background carries nothing
/// the asset can show: it is not cooked, and the report says so with its range (OpenVDB's own
/// min/max of the grid over the frames). Dropped down to one grid, the asset is the single-grid
/// cook of that grid, byte for byte; `--keep-empty-channels` keeps it; lossless cooks drop only
/// channels that are exactly their background.
#[test]
fn channels_that_carry_nothing_are_dropped_with_a_note() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("a.vdbc");
    let r = cook(&out, &["--max-error", "0.01,temperature=5,flame=5"]);
    let dropped = r["dropped_channels"].as_array().unwrap();
    assert_eq!(dropped.len(), 1, "{dropped:?}");
    assert_eq!(dropped[0]["name"], "flame");
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for f in 0..4 {
        let t = fire_truth(f, "flame");
        if t["active_voxels"].as_u64().unwrap() > 0 {
            lo = lo.min(t["value_min"].as_f64().unwrap());
            hi = hi.max(t["value_max"].as_f64().unwrap());
        }
    }
    assert_eq!(dropped[0]["value_range"][0].as_f64().unwrap(), lo);
    assert_eq!(dropped[0]["value_range"][1].as_f64().unwrap(), hi);
    let names: Vec<&str> = r["channels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["density", "temperature"]);
    let info = json(&["info", "--json", out.to_str().unwrap()]);
    assert_eq!(info["channels"].as_array().unwrap().len(), 2);
    // Down to one grid: the single-grid cook.
    let one = d.path().join("one.vdbc");
    let r = json(&[
        "cook",
        "--json",
        FIRE,
        "--grids",
        "density,flame",
        "--max-error",
        "density=0.01,flame=5",
        "-o",
        one.to_str().unwrap(),
    ]);
    assert_eq!(r["dropped_channels"][0]["name"], "flame");
    let single = d.path().join("single.vdbc");
    json(&[
        "cook",
        "--json",
        FIRE,
        "--grid",
        "density",
        "--max-error",
        "0.01",
        "-o",
        single.to_str().unwrap(),
    ]);
    assert!(
        std::fs::read(&one).unwrap() == std::fs::read(&single).unwrap(),
        "not the single-grid asset"
    );
    // Kept when asked; a lossless cook drops none of the fire's grids.
    let kept = d.path().join("kept.vdbc");
    let r = cook(
        &kept,
        &[
            "--max-error",
            "0.01,temperature=5,flame=5",
            "--keep-empty-channels",
        ],
    );
    assert_eq!(r["channels"].as_array().unwrap().len(), 3);
    assert!(r["dropped_channels"].as_array().unwrap().is_empty());
    let r = cook(&d.path().join("lossless.vdbc"), &[]);
    assert!(r["dropped_channels"].as_array().unwrap().is_empty());
}

/// `inspect` suggests the grids of a fire cache by name (the fixture's writer names them as
/// Houdini and EmberGen do), leaving out a grid on another transform with why; `cook --grids
/// auto` cooks exactly what `--grids` naming them cooks, and refuses clearly where nothing
/// matches or where several grids are not supported.
#[test]
fn grids_auto_cooks_what_inspect_suggests() {
    let d = tempfile::tempdir().unwrap();
    let ins = json(&["inspect", "--json", &format!("{FIRE}/fire.0001.vdb")]);
    assert_eq!(ins["files"][0]["suggested_grids"], serde_json::json!(GRIDS));
    let mixed = json(&["inspect", "--json", "fixtures/vdb/fire_mixed_xform.vdb"]);
    let skipped = &mixed["files"][0]["suggested_skipped"][0];
    assert_eq!(skipped["name"], "temperature");
    assert!(skipped["why"].as_str().unwrap().contains("transform"));
    let auto = d.path().join("auto.vdbc");
    let named = d.path().join("named.vdbc");
    json(&[
        "cook",
        "--json",
        FIRE,
        "--grids",
        "auto",
        "--max-error",
        "0.01,temperature=5",
        "-o",
        auto.to_str().unwrap(),
    ]);
    cook(&named, &["--max-error", "0.01,temperature=5"]);
    assert!(std::fs::read(&auto).unwrap() == std::fs::read(&named).unwrap());
    let out = d.path().join("x.vdbc");
    let o = out.to_str().unwrap();
    refused(
        &[
            "cook",
            "fixtures/vdb/levelset_sphere.vdb",
            "--grids",
            "auto",
            "-o",
            o,
        ],
        &out,
        &["--grids auto", "no float grid", "float grids: "],
    );
}
