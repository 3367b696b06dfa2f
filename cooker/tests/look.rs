//! The production look (issue 32) as a user meets it through `vdbcook render`: fire glows by
//! its tool's convention (Blender/Mantaflow, Houdini, Kelvin) where flame or heat is high and
//! nowhere else; the up axis comes from the source; every PNG goes through one colour pipeline
//! (its bytes are the tone-mapped, sRGB-encoded PFM radiance, with and without a plate); EXR is
//! the linear radiance as the `exr` crate reads it back; a level set is refused, never drawn as
//! a flat fog.

mod common;

use std::path::Path;

use common::{gpu_required, json, read_pfm, read_png, vdbcook};
use serde_json::Value;

const W: u32 = 128;
const H: u32 = 96;

/// The pixel a world point projects to, through the camera matrices `render --json` reports.
fn project(doc: &Value, p: [f64; 3]) -> (usize, usize) {
    let m = |k: &str| -> Vec<Vec<f64>> {
        doc["camera"][k]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| {
                r.as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect()
            })
            .collect()
    };
    let (v, pr) = (m("view_matrix"), m("projection_matrix"));
    let mul = |a: &Vec<Vec<f64>>, x: [f64; 4]| -> [f64; 4] {
        std::array::from_fn(|i| (0..4).map(|j| a[i][j] * x[j]).sum())
    };
    let c = mul(&pr, mul(&v, [p[0], p[1], p[2], 1.0]));
    let (x, y) = (c[0] / c[3], c[1] / c[3]);
    (
        ((x * 0.5 + 0.5) * W as f64) as usize,
        ((0.5 - y * 0.5) * H as f64) as usize,
    )
}

/// Warmth of the 3×3 pixels around `(i, j)`: the largest red minus blue (8-bit).
fn warmth(px: &[u8], (i, j): (usize, usize)) -> i32 {
    let mut best = i32::MIN;
    for y in j.saturating_sub(1)..=(j + 1).min(H as usize - 1) {
        for x in i.saturating_sub(1)..=(i + 1).min(W as usize - 1) {
            let k = 4 * (y * W as usize + x);
            best = best.max(px[k] as i32 - px[k + 2] as i32);
        }
    }
    best
}

/// `vdbcook render INPUT -o OUT --width W --height H EXTRA...`: exit code and stderr.
fn run_render(input: &str, out: &Path, extra: &[&str]) -> (i32, String) {
    let (w, h) = (W.to_string(), H.to_string());
    let mut args = vec![
        "render",
        input,
        "-o",
        out.to_str().unwrap(),
        "--width",
        &w,
        "--height",
        &h,
    ];
    args.extend_from_slice(extra);
    let (code, _, err) = vdbcook(&args);
    (code, err)
}

/// `render` to `dir/name` (PNG) with `--json`: the document and the pixels.
fn render(dir: &Path, input: &str, name: &str, extra: &[&str]) -> (Value, Vec<u8>) {
    let out = dir.join(name);
    let (w, h) = (W.to_string(), H.to_string());
    let mut args = vec!["render", input, "-o", out.to_str().unwrap(), "--json"];
    args.extend_from_slice(&["--width", &w, "--height", &h]);
    args.extend_from_slice(extra);
    (json(&args), read_png(&out).2)
}

/// Index `ijk` of the conventions fixtures (voxel size 0.1, no translation) in world units.
fn world(ijk: [f64; 3]) -> [f64; 3] {
    ijk.map(|v| 0.1 * v)
}

/// The fixtures of `gen_fire_conventions.py`: the smoke ball's centre (16, 16, 16), the hot
/// core 7 voxels below it along the tool's up axis. The default render glows at the core and
/// not at the top of the ball, 14 voxels away, where flame and heat are zero; `--emission off`
/// glows nowhere. Each tool's convention and up axis are the ones `render --json` states.
#[test]
fn fire_glows_by_its_tools_convention_where_it_is_hot_and_nowhere_else() {
    let dir = tempfile::tempdir().unwrap();
    for (file, up, convention, channel) in [
        (
            "fixtures/vdb/fire_blender.vdb",
            [0.0, 0.0, 1.0],
            "flame",
            "flame",
        ),
        (
            "fixtures/vdb/fire_houdini.vdb",
            [0.0, 1.0, 0.0],
            "flame",
            "heat",
        ),
    ] {
        let core = world([0, 1, 2].map(|a| 16.0 - 7.0 * up[a]));
        let top = world([0, 1, 2].map(|a| 16.0 + 7.0 * up[a]));
        for mode in ["density", "lit"] {
            let (doc, px) = render(
                dir.path(),
                file,
                "fire.png",
                // Lit: thin smoke (scattering 0.1), so that the core shows through it.
                &["--mode", mode, "--backend", "cpu", "--scatter", "0.1"],
            );
            let e = &doc["settings"]["emission"];
            assert_eq!(e["convention"], convention, "{file}: {e}");
            assert_eq!(e["channel"], channel, "{file}: {e}");
            let got_up: Vec<f64> = doc["camera"]["up"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            assert_eq!(got_up, up.to_vec(), "{file}: up axis");
            let (hot, cold) = (
                warmth(&px, project(&doc, core)),
                warmth(&px, project(&doc, top)),
            );
            assert!(
                hot > 40,
                "{file} {mode}: the core is not glowing (red − blue {hot})"
            );
            // The top is smoke, not the background: what is judged there is covered.
            let (ti, tj) = project(&doc, top);
            let k = 4 * (tj * W as usize + ti);
            let off = (0..3).map(|c| px[k + c].abs_diff(px[c])).max().unwrap();
            assert!(
                off > 8,
                "{file} {mode}: the top of the smoke is not in the image"
            );
            assert!(
                cold < 12,
                "{file} {mode}: the cold top glows (red − blue {cold})"
            );
        }
        let (_, px) = render(
            dir.path(),
            file,
            "off.png",
            &["--emission", "off", "--backend", "cpu"],
        );
        let warm = px
            .chunks_exact(4)
            .filter(|p| p[0] as i32 - p[2] as i32 > 12)
            .count();
        assert_eq!(warm, 0, "{file}: --emission off still glows");
    }
    // Kelvin (fixtures/seq/fire: temperature 300..1800 K): glows from the Draper point, coloured
    // by its own temperatures.
    let (doc, px) = render(
        dir.path(),
        "fixtures/seq/fire/fire.0001.vdb",
        "kelvin.png",
        &["--backend", "cpu"],
    );
    let e = &doc["settings"]["emission"];
    assert_eq!(e["convention"], "kelvin", "{e}");
    assert_eq!(
        e["range"][0].as_f64().unwrap(),
        vdbcook_trace::DRAPER_KELVIN as f64
    );
    assert_eq!(e["range"], e["range_kelvin"]);
    assert!(px.chunks_exact(4).any(|p| p[0] as i32 - p[2] as i32 > 40));
    // `--up` overrides the source's convention.
    let (doc, _) = render(
        dir.path(),
        "fixtures/vdb/fire_blender.vdb",
        "y.png",
        &["--up", "y", "--backend", "cpu"],
    );
    assert_eq!(doc["camera"]["up"][1].as_f64().unwrap(), 1.0);
}

/// The GPU tracer glows where the CPU does (the same emission, resolved once).
#[test]
fn gpu_fire_glows_as_the_cpu_does() {
    let dir = tempfile::tempdir().unwrap();
    let file = "fixtures/vdb/fire_blender.vdb";
    let out = dir.path().join("gpu.png");
    let (code, err) = run_render(file, &out, &["--backend", "gpu"]);
    if code != 0 && !gpu_required() && err.contains("adapter") {
        eprintln!("skipped: no GPU adapter ({err})");
        return;
    }
    assert_eq!(code, 0, "{err}");
    let gpu = read_png(&out).2;
    let (_, cpu) = render(dir.path(), file, "cpu.png", &["--backend", "cpu"]);
    let warm = |px: &[u8]| {
        px.chunks_exact(4)
            .filter(|p| p[0] as i32 - p[2] as i32 > 40)
            .count()
    };
    let (g, c) = (warm(&gpu), warm(&cpu));
    assert!(c > 20, "the CPU render shows {c} glowing pixels");
    assert!(g.abs_diff(c) * 10 <= c, "GPU {g} glowing pixels, CPU {c}");
}

/// The RGBA pixels of a `W`×`H` EXR as the `exr` crate reads them (row 0 at the top).
fn read_exr(path: &Path) -> Vec<[f32; 4]> {
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| vec![[0f32; 4]; res.width() * res.height()],
        |px: &mut Vec<[f32; 4]>, pos, (r, g, b, a): (f32, f32, f32, f32)| {
            px[pos.y() * W as usize + pos.x()] = [r, g, b, a];
        },
    )
    .unwrap();
    img.layer_data.channel_data.pixels
}

/// The published curves, written here from their definitions in f64, apart from
/// `vdbcook_scene::display`: exposure, Khronos PBR Neutral, Narkowicz's ACES fit or a clamp,
/// then IEC 61966-2-1's sRGB encoding to 8 bits.
fn reference_display(rgb: [f32; 3], tonemap: &str, ev: f64) -> [u8; 3] {
    let c = rgb.map(|v| (v as f64).max(0.0) * ev.exp2());
    let m = match tonemap {
        "none" => c.map(|v| v.min(1.0)),
        "aces" => c.map(|v| {
            let x = 0.6 * v;
            (x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
        }),
        "pbr-neutral" => {
            let x = c[0].min(c[1]).min(c[2]);
            let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
            let c = c.map(|v| v - offset);
            let peak = c[0].max(c[1]).max(c[2]);
            if peak < 0.76 {
                c
            } else {
                let d = 0.24;
                let new_peak = 1.0 - d * d / (peak + d - 0.76);
                let g = 1.0 - 1.0 / (0.15 * (peak - new_peak) + 1.0);
                c.map(|v| (v * new_peak / peak) * (1.0 - g) + new_peak * g)
            }
        }
        t => panic!("no reference for {t}"),
    };
    m.map(|v| {
        let v = v.clamp(0.0, 1.0);
        let s = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    })
}

/// One colour pipeline: a PNG's bytes are the PFM's radiance (the same render) through exposure,
/// the tone map and the sRGB curve (as written here from the curves' definitions), alone (the
/// sky behind) and over a plate alike; over a plate the default (`auto`: no tone map) gives the
/// plate back byte for byte where the volume is not; the EXR is that radiance, opaque over the
/// sky; `--transparent` gives the volume's opacity as alpha, straight colour in the PNG and
/// premultiplied in the EXR.
#[test]
fn png_is_the_tone_mapped_radiance_and_exr_is_linear() {
    let dir = tempfile::tempdir().unwrap();
    let asset = common::cook_smoke(dir.path());
    let plate = dir.path().join("plate.png");
    let plate_px: Vec<u8> = (0..W * H)
        .flat_map(|k| [(k % 251) as u8, 90, 200, 255])
        .collect();
    std::fs::write(
        &plate,
        vdbcook::render::encode_png(W, H, &plate_px).unwrap(),
    )
    .unwrap();
    let plate_s = plate.to_str().unwrap().to_string();
    for (tonemap, ev, over) in [
        ("pbr-neutral", "0", None),
        ("aces", "1.5", None),
        ("none", "-1", None),
        ("pbr-neutral", "0", Some(plate_s.as_str())),
        ("auto", "0", Some(plate_s.as_str())),
    ] {
        let mut extra = vec!["--mode", "lit", "--backend", "cpu", "--tonemap", tonemap];
        if ev != "0" {
            extra.extend_from_slice(&["--exposure", ev]);
        }
        if let Some(p) = over {
            extra.extend_from_slice(&["--background", p]);
        }
        let (_, png) = render(dir.path(), &asset, "x.png", &extra);
        let pfm = dir.path().join("x.pfm");
        let (w, h) = (W.to_string(), H.to_string());
        let mut args = vec![
            "render",
            &asset,
            "-o",
            pfm.to_str().unwrap(),
            "--width",
            &w,
            "--height",
            &h,
        ];
        args.extend_from_slice(&extra);
        let (code, _, err) = vdbcook(&args);
        assert_eq!(code, 0, "{err}");
        let (_, _, rgb) = read_pfm(&pfm);
        let curve = match (tonemap, over) {
            ("auto", Some(_)) => "none",
            ("auto", None) => "pbr-neutral",
            (t, _) => t,
        };
        let ev_f: f64 = ev.parse().unwrap();
        let mut lit = 0;
        for (k, c) in rgb.chunks_exact(3).enumerate() {
            let want = reference_display([c[0], c[1], c[2]], curve, ev_f);
            for ch in 0..3 {
                let got = png[4 * k + ch];
                assert!(
                    (got as i32 - want[ch] as i32).abs() <= 1,
                    "{tonemap} {ev} EV over {over:?}: pixel {k} channel {ch}: PNG {got}, pipeline {}",
                    want[ch]
                );
            }
            lit += (c[0] > 0.3) as usize;
        }
        assert!(lit > 100, "{tonemap}: only {lit} bright pixels");
        if tonemap == "auto" {
            let same = (0..(W * H) as usize)
                .filter(|&k| png[4 * k..4 * k + 4] == plate_px[4 * k..4 * k + 4])
                .count();
            assert!(
                same > (W * H) as usize / 3,
                "the plate comes back where the volume is not: {same} pixels"
            );
        }
        // EXR (float and half) read back by the `exr` crate: the PFM's radiance.
        for half in [false, true] {
            let exr = dir.path().join("x.exr");
            let mut args = args.clone();
            args[3] = exr.to_str().unwrap();
            if half {
                args.push("--exr-half");
            }
            let (code, _, err) = vdbcook(&args);
            assert_eq!(code, 0, "{err}");
            let px = &read_exr(&exr);
            assert_eq!(px.len(), (W * H) as usize);
            let tol = if half { 1e-3 } else { 0.0 };
            for (k, c) in rgb.chunks_exact(3).enumerate() {
                for ch in 0..3 {
                    let (got, want) = (px[k][ch], c[ch]);
                    assert!(
                        (got - want).abs() <= tol * want.abs().max(1.0),
                        "EXR {half} {k}: {got} vs {want}"
                    );
                }
                // Opaque: the sky (alone) or the plate's alpha (255) behind.
                assert_eq!(px[k][3], 1.0, "EXR alpha {k}");
            }
        }
    }
    // --transparent: no sky; the PNG's alpha is the EXR's, its colour the EXR's divided by it.
    let (png_t, exr_t) = (dir.path().join("t.png"), dir.path().join("t.exr"));
    for out in [&png_t, &exr_t] {
        let extra = ["--mode", "lit", "--backend", "cpu", "--transparent"];
        let (code, err) = run_render(&asset, out, &extra);
        assert_eq!(code, 0, "{err}");
    }
    let png = read_png(&png_t).2;
    let px = &read_exr(&exr_t);
    let (mut clear, mut partial) = (0, 0);
    for (k, p) in px.iter().enumerate() {
        let a = p[3];
        assert!((0.0..=1.0).contains(&a));
        assert_eq!(png[4 * k + 3], (a * 255.0).round() as u8, "alpha {k}");
        clear += (a == 0.0) as usize;
        if a > 0.05 {
            partial += (a < 0.95) as usize;
            let want = reference_display([p[0] / a, p[1] / a, p[2] / a], "pbr-neutral", 0.0);
            for c in 0..3 {
                let got = png[4 * k + c];
                assert!(
                    (got as i32 - want[c] as i32).abs() <= 1,
                    "straight colour {k}"
                );
            }
        }
    }
    assert!(
        clear > px.len() / 3 && partial > 20,
        "{clear} clear, {partial} partly covered"
    );
}

/// A level set cooks exactly (its class kept in the asset), and every command that would march
/// its signed distance as a fog refuses it, naming what it is and what to do.
#[test]
fn level_sets_are_cooked_and_refused_by_the_fog_renderers() {
    let dir = tempfile::tempdir().unwrap();
    let asset = dir.path().join("ls.vdbc");
    let doc = json(&[
        "cook",
        "fixtures/vdb/levelset_sphere.vdb",
        "-o",
        asset.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(doc["error"]["exact"], true, "{doc}");
    let a = vdbcook_asset::Asset::from_bytes(&std::fs::read(&asset).unwrap()).unwrap();
    assert_eq!(a.header.source.grid_class, "level set");
    let out = dir.path().join("ls.png");
    for input in ["fixtures/vdb/levelset_sphere.vdb", asset.to_str().unwrap()] {
        for mode in ["density", "lit"] {
            let (code, _, err) = vdbcook(&[
                "render",
                input,
                "-o",
                out.to_str().unwrap(),
                "--mode",
                mode,
                "--backend",
                "cpu",
            ]);
            assert_eq!(code, 2, "{input} {mode}: {err}");
            assert!(
                err.contains("level set") && err.contains("fog volume"),
                "{err}"
            );
            assert!(!out.exists(), "no output on refusal");
        }
        // `report`'s renders too (its cooks would be fine, its images flat).
        if input.ends_with(".vdb") {
            let rep = dir.path().join("rep");
            let (code, _, err) = vdbcook(&[
                "report",
                input,
                "-o",
                rep.to_str().unwrap(),
                "--quick",
                "--no-gpu",
                "--no-peers",
            ]);
            assert_eq!(code, 2, "report {input}: {err}");
            assert!(err.contains("level set"), "{err}");
            assert!(!rep.join("report.md").exists());
        }
        let shot = dir.path().join("shot.png");
        let (code, _, err) = vdbcook(&["view", input, "--screenshot", shot.to_str().unwrap()]);
        assert_eq!(code, 2, "view {input}: {err}");
        assert!(err.contains("level set"), "{err}");
    }
}

/// Under `--units world` the steps not given are one voxel (three for shadows), not one world
/// unit: on a fog of 0.25-unit voxels the lit march steps 0.25 and draws what `--step 0.25`
/// draws, pixel for pixel, and a world-unit step (four voxels) draws something else.
#[test]
fn world_units_step_one_voxel_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let input = "fixtures/vdb/fog_f32_none_nomask.vdb";
    let base = ["--mode", "lit", "--units", "world", "--backend", "cpu"];
    let with = |name: &str, extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        render(dir.path(), input, name, &args)
    };
    let (doc, default) = with("default.png", &[]);
    let settings = &doc["settings"];
    assert!(
        (settings["step"].as_f64().unwrap() - 0.25).abs() < 1e-6,
        "{settings}"
    );
    assert!(
        (settings["shadow_step"].as_f64().unwrap() - 0.75).abs() < 1e-6,
        "{settings}"
    );
    let (_, voxel) = with("voxel.png", &["--step", "0.25", "--shadow-step", "0.75"]);
    assert_eq!(default, voxel);
    let (doc1, unit) = with("unit.png", &["--step", "1"]);
    assert!((doc1["settings"]["step"].as_f64().unwrap() - 1.0).abs() < 1e-6);
    assert_ne!(
        default, unit,
        "a step of four voxels should change the lit image"
    );
}
