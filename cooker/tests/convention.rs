//! Voxel positions follow OpenVDB (issue 18): the value of voxel `ijk` sits at the world position
//! of index `ijk`, and nearest lookup gives it `[ijk − ½, ijk + ½)`. The truth is
//! `fixtures/vdb/centres.rays.json`, computed by `fixtures/gen/gen_centres.py` with real OpenVDB
//! (its `worldToIndex` under a rotated, non-uniformly scaled, translated transform) and an exact
//! slab test against each voxel's box: per pixel of a pinhole camera, the world distance at which
//! the ray enters the first voxel over the cutoff, or a miss. Pixels whose ray grazes a voxel
//! edge (hit or first voxel changes within 1/50 pixel) are marked ambiguous and not judged.
//!
//! The CPU tracer is checked ray by ray on the truth's own directions (hit and distance); both
//! backends are checked through `vdbcook render --mode depth` (PNG alpha = hit). Under the old
//! cell convention (voxel `ijk` filling `[ijk, ijk + 1)`) 444 of the 1,903 judged rays had the
//! wrong hit or distance, and 69 pixels of the silhouette were wrong.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{gpu_required, read_png};
use serde_json::Value;
use vdbcook_asset::Asset;
use vdbcook_trace::{Camera, Integrator, Mode, Output, RenderSettings, Scratch, Tracer};

fn fixture(name: &str) -> PathBuf {
    vdbcook_testkit::fixtures().join("vdb").join(name)
}

fn truth() -> Value {
    let text = std::fs::read_to_string(fixture("centres.rays.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn v3(v: &Value) -> [f64; 3] {
    [0, 1, 2].map(|i| v[i].as_f64().unwrap())
}

fn camera(t: &Value) -> Camera {
    let c = &t["camera"];
    Camera {
        eye: v3(&c["eye"]),
        look_at: v3(&c["look_at"]),
        up: v3(&c["up"]),
        fov_y_deg: c["fov_y_deg"].as_f64().unwrap(),
    }
}

fn cook(dir: &Path) -> PathBuf {
    let out = dir.join("centres.vdbc");
    let o = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
        .arg("cook")
        .arg(fixture("centres.vdb"))
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

#[test]
fn cpu_first_hit_matches_openvdb_voxel_centres_ray_by_ray() {
    let t = truth();
    let dir = tempfile::tempdir().unwrap();
    let asset = Asset::load(cook(dir.path())).unwrap();
    let cam = camera(&t);
    let settings = RenderSettings {
        output: Output {
            width: t["width"].as_u64().unwrap() as u32,
            height: t["height"].as_u64().unwrap() as u32,
            ..Default::default()
        },
        integrator: Integrator {
            mode: Mode::Depth,
            cutoff: t["cutoff"].as_f64().unwrap() as f32,
            ..Default::default()
        },
        ..Default::default()
    };
    let tracer = Tracer::new(&asset, &cam, &settings).unwrap();
    let mut scratch = Scratch::default();
    let (mut judged, mut hits, mut bad) = (0, 0, Vec::new());
    for r in t["rays"].as_array().unwrap() {
        if r["ambiguous"].as_bool().unwrap() {
            continue;
        }
        judged += 1;
        let want = r["t"].as_f64().unwrap();
        let got = tracer.trace(cam.eye, v3(&r["dir"]), 0, &mut scratch).value as f64;
        let ok = if want < 0.0 {
            got < 0.0
        } else {
            hits += 1;
            // Depth values are f32: a few ulps of the distance (≈ 11 world units here).
            (got - want).abs() <= 1e-5 * want.max(1.0)
        };
        if !ok {
            bad.push(format!("pixel {}: want t {want}, got {got}", r["pixel"]));
        }
    }
    assert!(judged > 1800 && hits > 350, "judged {judged}, hits {hits}");
    assert!(
        bad.is_empty(),
        "{} of {judged} rays disagree with OpenVDB's voxel positions:\n{}",
        bad.len(),
        bad[..bad.len().min(12)].join("\n")
    );
}

fn read_alpha(path: &Path) -> (u32, u32, Vec<u8>) {
    let (w, h, px) = read_png(path);
    (w, h, px.chunks(4).map(|p| p[3]).collect())
}

#[test]
fn both_backends_draw_the_silhouette_openvdb_places() {
    let t = truth();
    let dir = tempfile::tempdir().unwrap();
    let asset = cook(dir.path());
    let c = &t["camera"];
    let (e, l) = (v3(&c["eye"]), v3(&c["look_at"]));
    let cam = format!(
        "{},{},{},{},{},{},{}",
        e[0],
        e[1],
        e[2],
        l[0],
        l[1],
        l[2],
        c["fov_y_deg"].as_f64().unwrap()
    );
    let (w, h) = (t["width"].as_u64().unwrap(), t["height"].as_u64().unwrap());
    for backend in ["cpu", "gpu"] {
        let png = dir.path().join(format!("{backend}.png"));
        let o = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
            .arg("render")
            .arg(&asset)
            .args(["--mode", "depth", "--backend", backend, "--camera", &cam])
            .args(["--width", &w.to_string(), "--height", &h.to_string()])
            .args(["--cutoff", &t["cutoff"].to_string()])
            .arg("-o")
            .arg(&png)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        if backend == "gpu" && !o.status.success() && !gpu_required() {
            eprintln!("skipped the GPU half: {err}");
            continue;
        }
        assert!(o.status.success(), "{backend}: {err}");
        let (pw, ph, alpha) = read_alpha(&png);
        assert_eq!((pw as u64, ph as u64), (w, h));
        let mut bad = Vec::new();
        for r in t["rays"].as_array().unwrap() {
            if r["ambiguous"].as_bool().unwrap() {
                continue;
            }
            let (x, y) = (
                r["pixel"][0].as_u64().unwrap(),
                r["pixel"][1].as_u64().unwrap(),
            );
            let want = r["t"].as_f64().unwrap() >= 0.0;
            let got = alpha[(y * w + x) as usize] > 0;
            if want != got {
                bad.push(format!("({x},{y}) want hit {want}"));
            }
        }
        assert!(
            bad.is_empty(),
            "{backend}: {} pixels disagree with OpenVDB's silhouette: {}",
            bad.len(),
            bad.join(", ")
        );
    }
}
