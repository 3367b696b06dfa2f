//! `vdbcook view` as the tests can run it: headless (`--frames N --screenshot OUT.png`, no window,
//! the same per-frame code as the interactive loop). The screenshot has the asked size, shows the
//! volume, and equals what `vdbcook render --backend gpu` draws for the final frame, mode and
//! camera that `--json` reports (so the orbit, the flip-book stepping and the blit onto the
//! window's format are all checked); bad input is refused with a reason and a non-zero exit.
//! GPU cases skip without an adapter unless `VDBCOOK_REQUIRE_GPU=1`.

mod common;

use std::path::Path;

use common::{cook_smoke, gpu_required, read_png, vdbcook};
use serde_json::Value;

/// Runs a GPU command; `None` (skip) when there is no adapter and a GPU is not required.
fn gpu_run(args: &[&str]) -> Option<(i32, String, String)> {
    let (code, out, err) = vdbcook(args);
    if code != 0 && !gpu_required() && err.contains("no GPU adapter") {
        eprintln!("skipping: {err}");
        return None;
    }
    Some((code, out, err))
}

/// The largest difference of two images' bytes.
fn worst_diff(a: &[u8], b: &[u8]) -> u8 {
    a.iter().zip(b).map(|(x, y)| x.abs_diff(*y)).max().unwrap()
}

/// The `--camera` argument of `render` that reproduces a `view --json` run's final camera.
fn camera_arg(doc: &Value) -> String {
    let c = &doc["camera"];
    let num = |v: &Value| v.as_f64().unwrap().to_string();
    (0..3)
        .map(|i| num(&c["eye"][i]))
        .chain((0..3).map(|i| num(&c["look_at"][i])))
        .chain([num(&c["fov_y_deg"])])
        .collect::<Vec<_>>()
        .join(",")
}

#[test]
fn headless_screenshot_shows_the_volume_and_matches_render() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    for mode in ["density", "scatter"] {
        let shot = dir.path().join(format!("view-{mode}.png"));
        let Some((code, stdout, err)) = gpu_run(&[
            "view",
            &asset,
            "--frames",
            "5",
            "--screenshot",
            shot.to_str().unwrap(),
            "--width",
            "160",
            "--height",
            "90",
            "--mode",
            mode,
            // One sun for both (`--light auto` is placed from each command's starting camera,
            // and the view orbits away from it).
            "--light",
            "0.3,0.3,0",
            "--json",
        ]) else {
            return;
        };
        assert_eq!(code, 0, "{err}");
        let doc: Value = serde_json::from_str(&stdout).unwrap();
        // One flip-book frame per rendered frame: 0..4, each timed.
        let per_frame = doc["per_frame"].as_array().unwrap();
        assert_eq!(per_frame.len(), 5, "{doc}");
        for (i, f) in per_frame.iter().enumerate() {
            assert_eq!(f["frame"], i, "{doc}");
            assert!(f["cpu_ms"].as_f64().unwrap() > 0.0, "{doc}");
            if doc["timestamps"] == true {
                assert!(f["gpu_ms"].as_f64().unwrap() >= 0.0, "{doc}");
            }
        }
        assert_eq!(doc["frame"], 4);
        assert_eq!(doc["mode"], mode);

        let (w, h, px) = read_png(&shot);
        assert_eq!((w, h), (160, 90));
        // The volume is there: many pixels differ from the corner (background), and the centre
        // region is not all background.
        let bg = &px[..4];
        let lit = px.chunks(4).filter(|p| p[..3] != bg[..3]).count();
        assert!(
            lit > 160 * 90 / 20,
            "{mode}: only {lit} pixels differ from the background"
        );
        let centre_lit = (30..60)
            .flat_map(|y| (55..105).map(move |x| (y, x)))
            .filter(|&(y, x)| {
                let p = &px[4 * (y * 160 + x)..][..4];
                p[..3] != bg[..3]
            })
            .count();
        assert!(
            centre_lit > 30 * 50 / 4,
            "{mode}: centre mostly background ({centre_lit})"
        );

        // `render` with the reported camera draws the same picture.
        let cam = camera_arg(&doc);
        let reference = dir.path().join(format!("render-{mode}.png"));
        let (code, _, err) = vdbcook(&[
            "render",
            &asset,
            "-o",
            reference.to_str().unwrap(),
            "--backend",
            "gpu",
            "--frame",
            "4",
            "--mode",
            mode,
            "--width",
            "160",
            "--height",
            "90",
            "--camera",
            &cam,
            "--light",
            "0.3,0.3,0",
        ]);
        assert_eq!(code, 0, "{err}");
        let (_, _, want) = read_png(&reference);
        let worst = worst_diff(&px, &want);
        assert!(worst <= 2, "{mode}: view and render differ by {worst}/255");
    }
}

#[test]
fn screenshot_alone_renders_one_frame() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let shot = dir.path().join("one.png");
    let Some((code, stdout, err)) = gpu_run(&[
        "view",
        &asset,
        "--screenshot",
        shot.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--frame",
        "2",
        "--json",
    ]) else {
        return;
    };
    assert_eq!(code, 0, "{err}");
    let doc: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(doc["per_frame"].as_array().unwrap().len(), 1, "{doc}");
    assert_eq!(doc["frame"], 2);
    assert_eq!(read_png(&shot).0, 64);
}

/// The fire fixture's temperature grid glows in the viewer's density mode with `--emission`
/// and by default (a Kelvin grid's convention): warm pixels (red over green over blue), none
/// with `--emission off`.
#[test]
fn emission_glows_in_the_density_mode() {
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("fire.png");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "view",
            "fixtures/seq/fire/fire.0002.vdb",
            "--grid",
            "temperature",
            "--absorb",
            "0",
            "--screenshot",
            shot.to_str().unwrap(),
            "--width",
            "96",
            "--height",
            "96",
        ];
        args.extend_from_slice(extra);
        warm_pixels(&args, &shot)
    };
    let Some(glow) = run(&["--emission", "700,1800"]) else {
        return;
    };
    assert!(glow > 200, "only {glow} glowing pixels");
    assert_eq!(
        run(&["--emission", "off"]),
        Some(0),
        "no glow with --emission off"
    );
    // By default the Kelvin grid glows by its convention.
    assert!(run(&[]).unwrap() > 200, "no glow by default");
}

/// Runs `view` with `args` (a screenshot to `shot`) and counts the glowing pixels of the
/// screenshot (red above 40, red ≥ green ≥ blue); `None` where no GPU adapter may be skipped.
fn warm_pixels(args: &[&str], shot: &std::path::Path) -> Option<usize> {
    let (code, _, err) = gpu_run(args)?;
    assert_eq!(code, 0, "{err}");
    let (_, _, px) = read_png(shot);
    Some(
        px.chunks(4)
            .filter(|p| p[0] > 40 && p[0] > p[1] && p[1] >= p[2])
            .count(),
    )
}

/// A multi-channel fire glows from its temperature channel in the viewer, as `render` draws it
/// (issue 31): `--emission` alone picks the temperature channel; `--emission-grid density` reads
/// the density's values (0..1) as Kelvin, which glow nowhere.
#[test]
fn a_multi_channel_fire_glows_from_its_temperature_channel() {
    let dir = tempfile::tempdir().unwrap();
    let fire = dir.path().join("fire.vdbc");
    let (code, _, err) = common::vdbcook(&[
        "cook",
        "fixtures/seq/fire",
        "--grids",
        "density,temperature,flame",
        "-o",
        fire.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let shot = dir.path().join("fire.png");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "view",
            fire.to_str().unwrap(),
            "--frame",
            "1",
            "--emission",
            "700,1800",
            "--screenshot",
            shot.to_str().unwrap(),
            "--width",
            "96",
            "--height",
            "96",
        ];
        args.extend_from_slice(extra);
        warm_pixels(&args, &shot)
    };
    let Some(glow) = run(&[]) else {
        return;
    };
    assert!(glow > 200, "only {glow} glowing pixels");
    assert_eq!(run(&["--emission-grid", "density"]), Some(0));
    let (code, _, err) = common::vdbcook(&[
        "view",
        fire.to_str().unwrap(),
        "--emission",
        "700,1800",
        "--emission-grid",
        "soot",
        "--frames",
        "1",
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("soot"), "{err}");
}

#[test]
fn bad_input_is_refused_with_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let shot = dir.path().join("x.png");
    let shot = shot.to_str().unwrap();
    let missing = dir.path().join("missing.vdbc");
    let missing = missing.to_str().unwrap();
    let cases: [(&[&str], i32, &str); 8] = [
        (
            &["view", &asset, "--emission", "5", "--frames", "1"],
            2,
            "--emission",
        ),
        (
            &["view", &asset, "--emission", "900,800", "--frames", "1"],
            2,
            "emission range",
        ),
        (&["view", missing, "--frames", "1"], 1, "missing.vdbc"),
        (&["view", &asset, "--frames", "0"], 2, "--frames 0"),
        (
            &["view", &asset, "--mode", "sparkle", "--frames", "1"],
            2,
            "sparkle",
        ),
        (
            &["view", &asset, "--frame", "9", "--frames", "1"],
            2,
            "--frame 9",
        ),
        (&["view", &asset, "--screenshot", "x.jpg"], 2, ".png"),
        (&["view", &asset, "--json"], 2, "--frames"),
    ];
    for (args, want, says) in cases {
        let (code, _, err) = vdbcook(args);
        assert_eq!(code, want, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    assert!(!Path::new(shot).exists());
}

/// The viewer's blit runs the colour pipeline `render` runs (`shaders/display.wgsl` against
/// `vdbcook_scene::Display`): each tone map at an exposure that pushes the smoke past display
/// white, within 2/255 of `render`'s PNG of the same view.
#[test]
fn the_viewer_tone_maps_as_render_does() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    // The lit mode adds the sky behind the volume (the blit's sky flag).
    for (tonemap, ev, mode) in [
        ("aces", "1", "density"),
        ("pbr-neutral", "2", "density"),
        ("none", "0.5", "density"),
        ("pbr-neutral", "0", "lit"),
    ] {
        let shot = dir.path().join(format!("view-{tonemap}-{mode}.png"));
        let look = [
            "--tonemap",
            tonemap,
            "--exposure",
            ev,
            "--mode",
            mode,
            "--width",
            "96",
            "--height",
            "64",
        ];
        let mut args = vec![
            "view",
            &asset,
            "--screenshot",
            shot.to_str().unwrap(),
            "--json",
        ];
        args.extend_from_slice(&look);
        let Some((code, stdout, err)) = gpu_run(&args) else {
            return;
        };
        assert_eq!(code, 0, "{err}");
        let doc: Value = serde_json::from_str(&stdout).unwrap();
        let reference = dir.path().join(format!("render-{tonemap}-{mode}.png"));
        let cam = camera_arg(&doc);
        let mut args = vec![
            "render",
            &asset,
            "-o",
            reference.to_str().unwrap(),
            "--backend",
            "gpu",
            "--camera",
            &cam,
        ];
        args.extend_from_slice(&look);
        let (code, _, err) = vdbcook(&args);
        assert_eq!(code, 0, "{err}");
        let (_, _, px) = read_png(&shot);
        let (_, _, want) = read_png(&reference);
        let worst = worst_diff(&px, &want);
        assert!(
            worst <= 2,
            "{tonemap} {mode}: view and render differ by {worst}/255"
        );
        let white = want.chunks(4).filter(|p| p[0] >= 128).count();
        assert!(
            white > 50,
            "{tonemap} at {ev} EV: only {white} bright pixels"
        );
    }
}
