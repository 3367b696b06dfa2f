//! `vdbcook render` over a scene, as a compositor or a CI job runs it: `--background PLATE.png`
//! and `--depth DEPTH.pfm` with PNG and PFM output, on the CPU reference and (where an adapter
//! exists) the GPU engine drawer. Checks the compositing relation `out = L + T·plate` per pixel
//! for two plates (exactly in PFM, within 8-bit rounding in PNG), depth planes in front of the
//! cloud (plate untouched), beyond it (no change), through it (part cut, GPU = CPU), the PFM
//! round trip against the PNG, the camera matrices of `--json`, and the refusals (wrong sizes,
//! malformed PFM, colour PFM as depth, `.jpg`, `--depth` on a mode that cannot cut): exit
//! non-zero, a reason naming the file, nothing written.

mod common;

use std::path::Path;

use common::{cook_smoke, read_pfm, vdbcook};
use serde_json::Value;

const W: u32 = 96;
const H: u32 = 64;

fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb8(x: f32) -> u8 {
    let x = x.clamp(0.0, 1.0);
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// Writes an 8-bit RGB PNG of `W × H` from `f(x, y)`; returns its pixels.
fn write_plate(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) -> Vec<[u8; 3]> {
    let px: Vec<[u8; 3]> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| f(x, y))
        .collect();
    let mut enc = png::Encoder::new(std::fs::File::create(path).unwrap(), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let data: Vec<u8> = px.iter().flatten().copied().collect();
    enc.write_header().unwrap().write_image_data(&data).unwrap();
    px
}

/// Writes a greyscale PFM (`Pf`, little-endian) of constant depth `d`.
fn write_depth(path: &Path, w: u32, h: u32, d: f32) {
    let mut b = format!("Pf\n{w} {h}\n-1.0\n").into_bytes();
    for _ in 0..w * h {
        b.extend_from_slice(&d.to_le_bytes());
    }
    std::fs::write(path, b).unwrap();
}

fn read_png(path: &Path) -> Vec<u8> {
    let (w, h, px) = common::read_png(path);
    assert_eq!((w, h), (W, H));
    px
}

/// `vdbcook render ASSET -o OUT --frame 2 --width W --height H --backend B EXTRA...`: stdout,
/// or `None` when the GPU backend has no adapter and GPU tests may skip.
fn render(asset: &str, out: &Path, backend: &str, extra: &[&str]) -> Option<String> {
    let (w, h) = (W.to_string(), H.to_string());
    let mut args = vec![
        "render",
        asset,
        "-o",
        out.to_str().unwrap(),
        "--frame",
        "2",
        "--width",
        &w,
        "--height",
        &h,
        "--backend",
        backend,
    ];
    args.extend_from_slice(extra);
    let (code, stdout, err) = vdbcook(&args);
    let required = std::env::var_os("VDBCOOK_REQUIRE_GPU").is_some_and(|v| v != "0");
    if backend == "gpu" && code != 0 && !required && err.contains("no GPU adapter") {
        eprintln!("skipping the GPU half: {err}");
        return None;
    }
    assert_eq!(code, 0, "{args:?}: {err}");
    Some(stdout)
}

fn plates(dir: &Path) -> [(String, Vec<[u8; 3]>); 2] {
    let a = dir.join("plate_a.png");
    let b = dir.join("plate_b.png");
    let pa = write_plate(&a, W, H, |x, y| {
        [(x * 255 / W) as u8, (y * 255 / H) as u8, 128]
    });
    let pb = write_plate(&b, W, H, |x, y| {
        if (x / 8 + y / 8) % 2 == 0 {
            [250, 240, 20]
        } else {
            [10, 30, 90]
        }
    });
    [(a.display().to_string(), pa), (b.display().to_string(), pb)]
}

#[test]
fn composite_is_radiance_plus_transmittance_times_the_plate() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    // Alone: the density mode's L = 1 − T (grey), linear in the PFM.
    let alone = dir.path().join("alone.pfm");
    render(&asset, &alone, "cpu", &[]).unwrap();
    let (w, h, l) = read_pfm(&alone);
    assert_eq!((w, h), (W, H));
    let covered = l.iter().filter(|&&v| v > 0.02).count();
    assert!(covered > l.len() / 20, "the cloud covers part of the frame");
    // PFM round trip: the PNG alone is the same values through the colour pipeline (no tone
    // map: the sRGB curve alone).
    let alone_png = dir.path().join("alone.png");
    render(&asset, &alone_png, "cpu", &["--tonemap", "none"]).unwrap();
    let png = read_png(&alone_png);
    for (k, v) in l.iter().enumerate() {
        let (p, c) = (k / 3, k % 3);
        assert_eq!(png[4 * p + c], vdbcook_trace::linear_to_srgb8(*v));
    }
    for (name, (plate, px)) in plates(dir.path()).iter().enumerate() {
        let pfm = dir.path().join(format!("over{name}.pfm"));
        let pngp = dir.path().join(format!("over{name}.png"));
        render(&asset, &pfm, "cpu", &["--background", plate]).unwrap();
        render(&asset, &pngp, "cpu", &["--background", plate]).unwrap();
        let (_, _, out) = read_pfm(&pfm);
        let png = read_png(&pngp);
        let mut max_err = 0.0f32;
        for p in 0..(W * H) as usize {
            for c in 0..3 {
                let lv = l[3 * p + c];
                let want = lv + (1.0 - lv) * srgb_to_linear(px[p][c]);
                max_err = max_err.max((out[3 * p + c] - want).abs());
                // The PNG is the sRGB encoding of the PFM (round trip within 8-bit rounding).
                let got = png[4 * p + c] as i32;
                assert!(
                    (got - linear_to_srgb8(out[3 * p + c]) as i32).abs() <= 1,
                    "pixel {p} channel {c}"
                );
                assert!((got - linear_to_srgb8(want) as i32).abs() <= 1);
            }
            assert_eq!(png[4 * p + 3], 255, "the plate's alpha");
        }
        assert!(
            max_err < 2e-6,
            "{plate}: out = L + T·plate off by {max_err}"
        );
    }

    // The GPU engine drawer over the same plates: within the half-float storage of (L, T).
    for (name, (plate, _)) in plates(dir.path()).iter().enumerate() {
        let cpu = dir.path().join(format!("over{name}.pfm"));
        let gpu = dir.path().join(format!("gpu{name}.pfm"));
        let Some(stdout) = render(&asset, &gpu, "gpu", &["--background", plate, "--json"]) else {
            return;
        };
        let doc: Value = serde_json::from_str(&stdout).unwrap();
        assert_eq!(doc["backend"], "gpu");
        assert_eq!(doc["runtime_path"], "drawer");
        let (a, b) = (read_pfm(&cpu).2, read_pfm(&gpu).2);
        let max = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max);
        assert!(
            max < 4e-3,
            "{plate}: GPU and CPU composites differ by {max}"
        );
    }
}

#[test]
fn depth_planes_in_front_beyond_and_through_the_cloud() {
    depth_planes("density");
}

/// The lit mode stops at a depth as the density mode does (CPU: the cut lit march; GPU: the
/// engine drawer with lighting).
#[test]
fn lit_depth_planes_in_front_beyond_and_through_the_cloud() {
    depth_planes("lit");
}

/// The distance from the default camera's eye to its look-at point for `asset` (from a CPU
/// `render --json` into `dir/x.png`).
fn look_distance(asset: &str, dir: &Path) -> f32 {
    let json = render(asset, &dir.join("x.png"), "cpu", &["--json"]).unwrap();
    let doc: Value = serde_json::from_str(&json).unwrap();
    let v = |k: &str| -> Vec<f64> {
        doc["camera"][k]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (eye, look) = (v("eye"), v("look_at"));
    (0..3)
        .map(|i| (look[i] - eye[i]).powi(2))
        .sum::<f64>()
        .sqrt() as f32
}

fn depth_planes(mode: &str) {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let [(plate, px), _] = plates(dir.path());
    let dist = look_distance(&asset, dir.path());
    let plane = |name: &str, d: f32| {
        let p = dir.path().join(name);
        write_depth(&p, W, H, d);
        p.display().to_string()
    };
    let near = plane("near.pfm", 1e-3 * dist);
    let far = plane("far.pfm", 1e3 * dist);
    let inf = plane("inf.pfm", f32::INFINITY);
    let zero = plane("zero.pfm", 0.0);
    // The look-at point is the centre of the framed box: a plane there cuts the cloud.
    let mid = plane("mid.pfm", dist);
    let mut outs = std::collections::HashMap::new();
    for backend in ["cpu", "gpu"] {
        for (name, extra) in [
            ("none", vec!["--background", &plate]),
            ("near", vec!["--background", &plate, "--depth", &near]),
            ("far", vec!["--background", &plate, "--depth", &far]),
            ("inf", vec!["--background", &plate, "--depth", &inf]),
            ("zero", vec!["--background", &plate, "--depth", &zero]),
            ("mid", vec!["--background", &plate, "--depth", &mid]),
            // Alone: a black sky behind the lit mode (its light and background), so that the
            // cut volume is the whole image.
            ("mid_alone", vec!["--depth", &mid, "--sky", "0,0,0"]),
        ] {
            let out = dir.path().join(format!("{backend}-{name}.png"));
            let mut extra = extra;
            extra.extend(["--mode", mode]);
            if render(&asset, &out, backend, &extra).is_none() {
                break;
            }
            outs.insert((backend, name), read_png(&out));
        }
    }
    let plate_rgba: Vec<u8> = px.iter().flat_map(|p| [p[0], p[1], p[2], 255]).collect();
    let cpu = |n| &outs[&("cpu", n)];
    assert_eq!(
        cpu("near"),
        &plate_rgba,
        "a plane in front leaves the plate"
    );
    assert_ne!(cpu("none"), &plate_rgba);
    for n in ["far", "inf", "zero"] {
        assert_eq!(cpu(n), cpu("none"), "{n}: no cut");
    }
    let differ = |a: &[u8], b: &[u8]| a.iter().zip(b).filter(|(x, y)| x != y).count();
    assert!(differ(cpu("mid"), cpu("none")) > 50, "the mid plane cuts");
    assert!(
        differ(cpu("mid"), &plate_rgba) > 50,
        "smoke before the plane"
    );
    // Without a plate the cut density is the display grey (1 − T), and lighter nowhere. (Over
    // a scene the lit mode steps, as the engine drawer does: the uncut image too.)
    let alone = dir.path().join("alone.png");
    render(
        &asset,
        &alone,
        "cpu",
        &["--mode", mode, "--march", "steps", "--sky", "0,0,0"],
    )
    .unwrap();
    let alone = read_png(&alone);
    assert!(cpu("mid_alone").iter().zip(&alone).all(|(c, a)| c <= a));
    assert!(differ(cpu("mid_alone"), &alone) > 50);

    if outs.contains_key(&("gpu", "mid_alone")) {
        let gpu = |n| &outs[&("gpu", n)];
        assert_eq!(gpu("near"), &plate_rgba, "GPU: a plane in front");
        for n in ["none", "far", "inf", "zero", "mid", "mid_alone"] {
            let max = gpu(n)
                .iter()
                .zip(cpu(n))
                .map(|(a, b)| (*a as i32 - *b as i32).abs())
                .max()
                .unwrap();
            assert!(max <= 2, "{mode} {n}: GPU and CPU differ by {max}/255");
        }
    }
}

#[test]
fn json_camera_matrices_reproduce_the_view() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let out = dir.path().join("x.pfm");
    let json = render(
        &asset,
        &out,
        "cpu",
        &["--json", "--camera", "3,2,4,1.2,1.2,1.6,30"],
    )
    .unwrap();
    let doc: Value = serde_json::from_str(&json).unwrap();
    assert_eq!(doc["output_format"], "pfm");
    let c = &doc["camera"];
    let m = |k: &str| -> [[f64; 4]; 4] { serde_json::from_value(c[k].clone()).unwrap() };
    let (view, proj) = (m("view_matrix"), m("projection_matrix"));
    let near = c["near"].as_f64().unwrap();
    let mul = |m: &[[f64; 4]; 4], p: [f64; 4]| -> [f64; 4] {
        std::array::from_fn(|r| (0..4).map(|k| m[r][k] * p[k]).sum())
    };
    // The eye maps to the origin, the look-at point onto −Z at its distance.
    let e = mul(&view, [3.0, 2.0, 4.0, 1.0]);
    assert!(e[..3].iter().all(|v| v.abs() < 1e-9), "{e:?}");
    let dist = (1.8f64.powi(2) + 0.8f64.powi(2) + 2.4f64.powi(2)).sqrt();
    let l = mul(&view, [1.2, 1.2, 1.6, 1.0]);
    assert!(l[0].abs() < 1e-9 && l[1].abs() < 1e-9 && (l[2] + dist).abs() < 1e-9);
    // Projected: the centre of the screen, NDC depth near / distance (reversed Z).
    let p = mul(&proj, l);
    assert!((p[2] / p[3] - near / dist).abs() < 1e-12, "{p:?}");
    assert!(p[0].abs() < 1e-9 && p[1].abs() < 1e-9);
    // The top edge of the image is at fov/2 above the axis.
    let up = [0.0, (15f64).to_radians().tan() * dist, -dist, 1.0];
    let q = mul(&proj, up);
    assert!((q[1] / q[3] - 1.0).abs() < 1e-9, "{q:?}");
    assert_eq!(read_pfm(&out).0, W);
}

#[test]
fn bad_scene_inputs_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let asset = cook_smoke(dir.path());
    let p = |n: &str| dir.path().join(n).display().to_string();
    write_plate(Path::new(&p("small.png")), W - 1, H, |_, _| [0, 0, 0]);
    write_depth(Path::new(&p("small.pfm")), W, H + 1, 1.0);
    std::fs::write(p("magic.pfm"), b"P6\n96 64\n-1.0\n").unwrap();
    let mut truncated = format!("Pf\n{W} {H}\n-1.0\n").into_bytes();
    truncated.extend_from_slice(&[0; 100]);
    std::fs::write(p("truncated.pfm"), truncated).unwrap();
    let mut colour = format!("PF\n{W} {H}\n-1.0\n").into_bytes();
    colour.resize(colour.len() + (W * H * 12) as usize, 0);
    std::fs::write(p("colour.pfm"), colour).unwrap();
    std::fs::write(p("text.png"), b"not a png").unwrap();
    let (small, smallpfm, magic, trunc, col, text) = (
        p("small.png"),
        p("small.pfm"),
        p("magic.pfm"),
        p("truncated.pfm"),
        p("colour.pfm"),
        p("text.png"),
    );
    let out = p("out.png");
    let exr = p("out.jpg");
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (
            vec!["-o", &out, "--background", &small],
            "small.png",
            "95x64",
        ),
        (vec!["-o", &out, "--depth", &smallpfm], "small.pfm", "96x65"),
        (vec!["-o", &out, "--depth", &magic], "magic.pfm", "magic"),
        (
            vec!["-o", &out, "--depth", &trunc],
            "truncated.pfm",
            "bytes",
        ),
        (vec!["-o", &out, "--depth", &col], "colour.pfm", "greyscale"),
        (vec!["-o", &out, "--background", &text], "text.png", "PNG"),
        (vec!["-o", &exr], "out.jpg", ".pfm"),
        (
            vec!["-o", &out, "--mode", "scatter", "--depth", &smallpfm],
            "--depth",
            "density",
        ),
    ];
    for (extra, name, want) in cases {
        let mut args = vec!["render", asset.as_str(), "--width", "96", "--height", "64"];
        args.extend_from_slice(&extra);
        let (code, _, err) = vdbcook(&args);
        assert_ne!(code, 0, "{extra:?}");
        assert!(err.contains(name) && err.contains(want), "{extra:?}: {err}");
        assert!(!Path::new(&out).exists() && !Path::new(&exr).exists());
    }
}

/// Emission over a plate keeps its glow on both backends (the GPU: the engine drawer's emission
/// pass): the fire fixture's temperature grid with no absorption is `plate + L_e`, the same on
/// CPU and GPU (within the drawer's half-float (L, T)).
#[test]
fn emission_over_a_plate_keeps_its_glow_on_both_backends() {
    let dir = tempfile::tempdir().unwrap();
    let [(plate, px), _] = plates(dir.path());
    let fire = "fixtures/seq/fire";
    let extra = [
        "--grid",
        "temperature",
        "--emission",
        "700,1800",
        "--absorb",
        "0",
        "--background",
        plate.as_str(),
    ];
    let cpu = dir.path().join("fire_cpu.pfm");
    render(fire, &cpu, "cpu", &extra).unwrap();
    let (_, _, c) = read_pfm(&cpu);
    let glow = (0..(W * H) as usize)
        .filter(|&p| c[3 * p] > srgb_to_linear(px[p][0]) + 0.1)
        .count();
    assert!(glow > 50, "only {glow} glowing pixels over the plate");
    let gpu = dir.path().join("fire_gpu.pfm");
    if render(fire, &gpu, "gpu", &extra).is_none() {
        return;
    }
    let (_, _, g) = read_pfm(&gpu);
    for (k, (a, b)) in c.iter().zip(&g).enumerate() {
        assert!(
            (a - b).abs() <= 2e-3 * a.abs().max(1.0),
            "value {k}: cpu {a} gpu {b}"
        );
    }
}

/// Fire in the engine drawer (issue 31): a three-channel cook of the fire fixture glows from its
/// temperature channel (`--emission` picks it) over a plate, flat and lit, uncut and cut by a
/// depth plane through it; the GPU drawer (its emission pass over the channel's box) draws what
/// the CPU draws (its channel emission behind the density, cut at the same depth).
#[test]
fn fire_from_its_temperature_channel_glows_in_the_engine_drawer() {
    let dir = tempfile::tempdir().unwrap();
    let fire = dir.path().join("fire.vdbc").display().to_string();
    let (code, _, err) = vdbcook(&[
        "cook",
        "fixtures/seq/fire",
        "--grids",
        "density,temperature,flame",
        "-o",
        &fire,
    ]);
    assert_eq!(code, 0, "{err}");
    let [(plate, px), _] = plates(dir.path());
    let dist = look_distance(&fire, dir.path());
    let mid = dir.path().join("mid.pfm");
    write_depth(&mid, W, H, dist);
    let mid = mid.display().to_string();
    for mode in ["density", "lit"] {
        for cut in [false, true] {
            let mut extra = vec![
                "--mode",
                mode,
                "--emission",
                "700,1800",
                "--background",
                plate.as_str(),
                "--json",
            ];
            if cut {
                extra.extend(["--depth", mid.as_str()]);
            }
            let what = format!("{mode}{}", if cut { " cut" } else { "" });
            let cpu = dir.path().join(format!("cpu-{mode}-{cut}.png"));
            render(&fire, &cpu, "cpu", &extra).unwrap();
            let c = read_png(&cpu);
            // It glows: pixels much redder than the plate under them.
            let warm = (0..(W * H) as usize)
                .filter(|&p| c[4 * p] as i32 > px[p][0] as i32 + 40 && c[4 * p] > c[4 * p + 2])
                .count();
            assert!(warm > 30, "{what}: only {warm} glowing pixels");
            let gpu = dir.path().join(format!("gpu-{mode}-{cut}.png"));
            let Some(stdout) = render(&fire, &gpu, "gpu", &extra) else {
                return;
            };
            let doc: Value = serde_json::from_str(&stdout).unwrap();
            assert_eq!(doc["runtime_path"], "drawer", "{what}");
            let g = read_png(&gpu);
            let max = g
                .iter()
                .zip(&c)
                .map(|(a, b)| (*a as i32 - *b as i32).abs())
                .max()
                .unwrap();
            assert!(max <= 2, "{what}: GPU and CPU differ by {max}/255");
        }
    }
}
