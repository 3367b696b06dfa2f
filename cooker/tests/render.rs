//! `vdbcook render` as a user runs it: cook the smoke fixture with the binary, render every
//! mode to PNG (decoded back to check size, format and coverage), the `--json` keys, VDB input
//! (cooked in memory: the same image as rendering the cooked asset), the GPU backend against the
//! CPU reference, and the refusals (bad frame, bad camera) exiting non-zero with a reason.

mod common;

use std::path::Path;

use common::{cook_smoke, gpu_required, read_png, vdbcook};
use serde_json::Value;

#[test]
fn every_mode_renders_a_png_of_the_asked_size() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    for mode in [
        "density",
        "depth",
        "first-hit",
        "brick-hue",
        "steps",
        "scatter",
        "delta",
        "reference",
        "lit",
    ] {
        let out = dir.path().join(format!("{mode}.png"));
        let (code, stdout, err) = vdbcook(&[
            "render",
            &asset,
            "-o",
            out.to_str().unwrap(),
            "--mode",
            mode,
            // The volume's own coverage: no sky behind the shaded modes.
            "--transparent",
            "--frame",
            "2",
            "--width",
            "160",
            "--height",
            "90",
            "--spp",
            "4",
        ]);
        assert_eq!(code, 0, "{mode}: {err}");
        assert!(stdout.contains("wrote"), "{stdout}");
        let (w, h, px) = read_png(&out);
        assert_eq!((w, h, px.len()), (160, 90, 160 * 90 * 4), "{mode}");
        // Coverage: pixels that show the volume (alpha for hit and scatter modes, any colour
        // for density; steps paints every ray that crosses the extent).
        let covered = px
            .chunks(4)
            .filter(|p| match mode {
                "density" => p[0] > 0,
                _ => p[3] > 0 && (p[0] > 0 || p[1] > 0 || p[2] > 0 || mode == "scatter"),
            })
            .count() as f64
            / (w * h) as f64;
        assert!(
            covered >= 0.05,
            "{mode}: only {covered:.3} of the frame shows the volume"
        );
        if mode != "steps" {
            assert!(
                covered < 0.9,
                "{mode}: the volume fills {covered:.3} of the frame"
            );
        }
    }
}

#[test]
fn render_json_reports_settings_camera_and_timing() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let out = dir.path().join("x.png");
    let (code, stdout, err) = vdbcook(&[
        "render",
        &asset,
        "-o",
        out.to_str().unwrap(),
        "--json",
        "--width",
        "64",
        "--height",
        "48",
        "--mode",
        "scatter",
        "--light",
        "0,1,0,1,0.5,0.25",
        "--camera",
        "3,2,4,1.2,1.2,1.6,30",
    ]);
    assert_eq!(code, 0, "{err}");
    let doc: Value = serde_json::from_str(&stdout).expect("one JSON document");
    for k in [
        "output", "mode", "frame", "width", "height", "backend", "seconds", "camera", "settings",
    ] {
        assert!(!doc[k].is_null(), "missing {k}");
    }
    assert_eq!(doc["mode"], "scatter");
    assert_eq!(doc["backend"], "cpu");
    assert_eq!(doc["runtime_path"], "cpu");
    assert_eq!(
        (doc["width"].as_u64(), doc["height"].as_u64()),
        (Some(64), Some(48))
    );
    assert!(doc["seconds"].as_f64().unwrap() > 0.0);
    assert_eq!(doc["camera"]["eye"], serde_json::json!([3.0, 2.0, 4.0]));
    assert_eq!(doc["camera"]["fov_y_deg"], 30.0);
    assert_eq!(
        doc["settings"]["light_color"],
        serde_json::json!([1.0, 0.5, 0.25])
    );
    for k in [
        "absorb",
        "scatter",
        "light_dir",
        "step",
        "shadow_step",
        "cutoff",
        "gain",
        "sky",
        "phase_g",
        "phase_w",
        "bounces",
        "light_res",
        "ms_octaves",
        "ms",
        "filter",
        "sun_near",
        "near_scatter",
        "primary_lod",
    ] {
        assert!(!doc["settings"][k].is_null(), "missing settings.{k}");
    }
    assert_eq!(read_png(&out).0, 64);
}

#[test]
fn render_refusals_exit_non_zero_with_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let out = dir.path().join("x.png").display().to_string();
    let cases: [(&[&str], &str); 12] = [
        (&["--frame", "5"], "frame 5"),
        (&["--camera", "1,2,3"], "--camera takes 7 numbers"),
        (&["--step", "0"], "step"),
        (&["--light", "0,0,0"], "light"),
        (&["--mode", "reference", "--phase", "1.2"], "phase g"),
        (
            &["--mode", "reference", "--phase", "0.5,0.1"],
            "--phase takes 1 or 3",
        ),
        (&["--mode", "reference", "--sky", "1,1"], "--sky takes 3"),
        (&["--mode", "reference", "--bounces", "0"], "bounces"),
        (&["--mode", "lit", "--light-res", "1"], "light-res"),
        (&["--mode", "lit", "--ms-octaves", "9"], "ms-octaves"),
        (&["--mode", "lit", "--ms", "0.5,0.5"], "--ms takes A,B,C"),
        (&["--mode", "lit", "--sun-near", "1000"], "sun-near"),
    ];
    for (extra, want) in cases {
        let mut args = vec!["render", asset.as_str(), "-o", out.as_str()];
        args.extend_from_slice(extra);
        let (code, _, err) = vdbcook(&args);
        assert_eq!(code, 1, "{extra:?}");
        assert!(err.contains(want), "{extra:?}: {err}");
    }
    // Emission is drawn by the density mode; a bad range is refused.
    for (extra, want) in [
        (
            &["--emission", "800,2000", "--mode", "steps"][..],
            "emission is drawn by",
        ),
        (&["--emission", "2000,800"][..], "emission range"),
        (
            &["--emission", "800"][..],
            "--emission takes auto, off or LO,HI",
        ),
    ] {
        let mut args = vec!["render", asset.as_str(), "-o", out.as_str()];
        args.extend_from_slice(extra);
        let (code, _, err) = vdbcook(&args);
        assert_eq!(code, 1, "{extra:?}: {err}");
        assert!(err.contains(want), "{extra:?}: {err}");
    }
    // Emission with a depth cut is drawn now (composite.rs tests it): a missing depth file is
    // still refused, naming it.
    let (code, _, err) = vdbcook(&[
        "render",
        &asset,
        "-o",
        &out,
        "--emission",
        "800,2000",
        "--depth",
        "nope.pfm",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("nope.pfm"), "{err}");
    // The diffusion model solves the sky's light: the octaves' sky knob is refused with it.
    let (code, _, err) = vdbcook(&[
        "render", &asset, "-o", &out, "--mode", "lit", "--ms-sky", "0.5",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--ms-model octaves"), "{err}");
    // The reference is CPU only: asking the GPU for it is a usage error, before any work.
    let (code, _, err) = vdbcook(&[
        "render",
        &asset,
        "-o",
        &out,
        "--mode",
        "reference",
        "--backend",
        "gpu",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--backend cpu"), "{err}");
    // VDB input that does not read: the reader's error, naming the file.
    let (code, _, err) = vdbcook(&["render", "fixtures/nope.vdb", "-o", &out]);
    assert_eq!(code, 1);
    assert!(err.contains("nope.vdb"), "{err}");
    assert!(!Path::new(&out).exists(), "no PNG after a failure");
}

#[test]
fn vdb_input_is_cooked_in_memory_and_renders_as_its_asset_does() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let a = dir.path().join("a.png");
    let b = dir.path().join("b.png");
    for (input, out) in [(asset.as_str(), &a), ("fixtures/seq/smoke5", &b)] {
        let (code, _, err) = vdbcook(&[
            "render",
            input,
            "-o",
            out.to_str().unwrap(),
            "--backend",
            "cpu",
            "--frame",
            "3",
            "--mode",
            "scatter",
            "--width",
            "96",
            "--height",
            "64",
        ]);
        assert_eq!(code, 0, "{input}: {err}");
    }
    let (pa, pb) = (read_png(&a), read_png(&b));
    assert!(
        pa.2.iter().any(|&v| v > 0 && v < 255),
        "an image with content"
    );
    assert_eq!(pa, pb, "VDB input renders exactly as the cooked asset");
}

#[test]
fn gpu_backend_draws_what_the_cpu_reference_draws() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    for mode in ["density", "first-hit", "scatter"] {
        let mut pngs = Vec::new();
        for backend in ["cpu", "gpu"] {
            let out = dir.path().join(format!("{mode}-{backend}.png"));
            let (code, stdout, err) = vdbcook(&[
                "render",
                &asset,
                "-o",
                out.to_str().unwrap(),
                "--backend",
                backend,
                "--mode",
                mode,
                "--frame",
                "2",
                "--width",
                "128",
                "--height",
                "96",
                "--json",
            ]);
            if backend == "gpu" && code != 0 && !gpu_required() && err.contains("no GPU adapter") {
                eprintln!("skipping: {err}");
                return;
            }
            assert_eq!(code, 0, "{mode} {backend}: {err}");
            let doc: Value = serde_json::from_str(&stdout).unwrap();
            assert_eq!(doc["backend"], backend);
            assert_eq!(
                doc["runtime_path"],
                if backend == "gpu" { "tracer" } else { "cpu" }
            );
            if backend == "gpu" {
                assert!(doc["adapter"].is_string(), "{doc}");
            }
            pngs.push(read_png(&out));
        }
        let (cpu, gpu) = (&pngs[0].2, &pngs[1].2);
        assert_eq!(cpu.len(), gpu.len());
        let lit = cpu.chunks(4).filter(|p| p[3] > 0 && p[0] > 8).count();
        assert!(
            lit > cpu.len() / 4 / 20,
            "{mode}: the volume fills part of the frame ({lit} px)"
        );
        let max = cpu
            .iter()
            .zip(gpu.iter())
            .map(|(a, b)| (*a as i32 - *b as i32).abs())
            .max()
            .unwrap();
        assert!(max <= 2, "{mode}: GPU and CPU PNGs differ by {max}/255");
    }
}

/// The CPU's shaded modes write the same bytes whatever the thread count (the lit mode's light
/// volume is built in parallel slabs, the reference's paths per pixel): 1 and 3 threads.
#[test]
fn cpu_renders_are_byte_identical_at_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    for mode in ["lit", "reference", "scatter"] {
        let mut outs = Vec::new();
        for threads in ["1", "3"] {
            let out = dir.path().join(format!("{mode}-{threads}.pfm"));
            let o = std::process::Command::new(env!("CARGO_BIN_EXE_vdbcook"))
                .args([
                    "render",
                    &asset,
                    "-o",
                    out.to_str().unwrap(),
                    "--backend",
                    "cpu",
                ])
                .args([
                    "--mode", mode, "--width", "96", "--height", "54", "--spp", "4",
                ])
                .env("RAYON_NUM_THREADS", threads)
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{mode}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            outs.push(std::fs::read(&out).unwrap());
        }
        assert!(outs[0] == outs[1], "{mode}: 1 and 3 threads differ");
    }
}

/// `--march auto` (the default) follows voxels on a dense frame and steps on a thin one, and
/// steps over a scene (the engine drawer's march); `--json` names the march that ran. The
/// smoke fixture's densest voxel is 0.9: one 1-voxel step through it has optical depth 1.45 in
/// the default medium, 0.1 in a thin one.
#[test]
fn lit_json_names_the_march_it_took() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let out = dir.path().join("lit.png").display().to_string();
    let plate = dir.path().join("plate.png");
    std::fs::write(
        &plate,
        vdbcook::render::encode_png(32, 18, &[128u8; 32 * 18 * 4]).unwrap(),
    )
    .unwrap();
    let plate = plate.display().to_string();
    for (extra, want) in [
        (&[][..], "voxels"),
        (&["--absorb", "0.01", "--scatter", "0.1"][..], "steps"),
        (&["--march", "steps"][..], "steps"),
        (&["--background", plate.as_str()][..], "steps"),
    ] {
        let mut args = vec![
            "render",
            &asset,
            "-o",
            &out,
            "--mode",
            "lit",
            "--width",
            "32",
            "--height",
            "18",
            "--backend",
            "cpu",
            // The march of the nearest filter (trilinear always steps).
            "--filter",
            "nearest",
            "--json",
        ];
        args.extend_from_slice(extra);
        let (code, stdout, err) = vdbcook(&args);
        assert_eq!(code, 0, "{extra:?}: {err}");
        let doc: Value = serde_json::from_str(&stdout).unwrap();
        assert_eq!(doc["settings"]["march_used"], want, "{extra:?}");
        let asked = if extra.contains(&"--march") {
            "steps"
        } else {
            "auto"
        };
        assert_eq!(doc["settings"]["march"], asked, "{extra:?}");
    }
}
