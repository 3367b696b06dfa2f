//! `vdbcook render` as a user runs it: cook the smoke fixture with the binary, render every
//! mode to PNG (decoded back to check size, format and coverage), the `--json` keys, and the
//! refusals (GPU backend, VDB input, bad frame, bad camera) exiting non-zero with a reason.

mod common;

use std::path::Path;

use common::vdbcook;
use serde_json::Value;

fn cook_smoke(dir: &Path) -> String {
    let asset = dir.join("smoke5.vdbc").display().to_string();
    let (code, _, err) = vdbcook(&["cook", "fixtures/seq/smoke5", "-o", &asset]);
    assert_eq!(code, 0, "{err}");
    asset
}

/// Width, height and 8-bit RGBA pixels of a PNG.
fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

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
    ] {
        let out = dir.path().join(format!("{mode}.png"));
        let (code, stdout, err) = vdbcook(&[
            "render",
            &asset,
            "-o",
            out.to_str().unwrap(),
            "--mode",
            mode,
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
    let cases: [(&[&str], &str); 5] = [
        (&["--backend", "gpu"], "GPU backend is not built yet"),
        (&["--frame", "5"], "frame 5"),
        (&["--camera", "1,2,3"], "--camera takes 7 numbers"),
        (&["--step", "0"], "step"),
        (&["--light", "0,0,0"], "light"),
    ];
    for (extra, want) in cases {
        let mut args = vec!["render", asset.as_str(), "-o", out.as_str()];
        args.extend_from_slice(extra);
        let (code, _, err) = vdbcook(&args);
        assert_eq!(code, 1, "{extra:?}");
        assert!(err.contains(want), "{extra:?}: {err}");
    }
    // VDB input: a clear "cook it first".
    let (code, _, err) = vdbcook(&["render", "fixtures/seq/smoke5", "-o", &out]);
    assert_eq!(code, 1);
    assert!(err.contains("cook it first"), "{err}");
    let (code, _, err) = vdbcook(&[
        "render",
        "fixtures/seq/smoke5/smoke.0001.vdb",
        "-o",
        &out,
        "--json",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("cook it first"), "{err}");
}
