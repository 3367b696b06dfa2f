//! Every cook option composes with every other (issue 31): several grids with clustering, a size
//! budget, levels of detail, a frame range and the batch manifest, each channel held to its own
//! budget as `eval` measures it against the source files (independent of the cook's own report);
//! and the manifest's cache serves only intact entries and survives concurrent runs.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use common::{gpu_bytes, json, root, vdbcook as run};
use serde_json::Value;
use vdbcook_asset::{Asset, LeafRef};

const FIRE: &str = "fixtures/seq/fire";
const GRIDS: &str = "density,temperature,flame";

/// The three fire grids as BC7 under the per-channel `spec`, clustered, written to `out`: the
/// cook's arguments after `cook` (one list, so cooks compared for identity get the same flags).
fn clustered<'a>(spec: &'a str, out: &'a str) -> [&'a str; 13] {
    [
        FIRE,
        "--grids",
        GRIDS,
        "--format",
        "bc7",
        "--max-error",
        spec,
        "--clusters",
        "24",
        "--variance-threshold",
        "100",
        "-o",
        out,
    ]
}

/// `eval`'s largest error per channel name.
fn eval_channels(asset: &str, input: &[&str]) -> BTreeMap<String, f64> {
    let mut args = vec!["eval", "--json", asset];
    args.extend_from_slice(input);
    let e = json(&args);
    e["channels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["name"].as_str().unwrap().to_string(),
                c["max_abs"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// Stored bricks read by more than one channel of the asset.
fn shared_bricks(path: &str) -> usize {
    let a = Asset::load(root().join(path)).unwrap();
    let mut readers: BTreeMap<u32, u8> = BTreeMap::new();
    for f in 0..a.frame_count() {
        for c in 0..a.channel_count() {
            a.for_each_leaf_c(f, c, |_, r, _| {
                if let LeafRef::Brick(b) = r {
                    *readers.entry(b).or_default() |= 1 << c;
                }
            });
        }
    }
    readers.values().filter(|m| m.count_ones() > 1).count()
}

#[test]
fn several_grids_cluster_per_channel_within_each_budget() {
    let d = tempfile::tempdir().unwrap();
    let budgets = [("density", 0.1), ("temperature", 100.0), ("flame", 0.2)];
    let spec = "density=0.1,temperature=100,flame=0.2";
    let plain = d.path().join("plain.vdbc");
    let c0 = json(&[
        "cook",
        "--json",
        FIRE,
        "--grids",
        GRIDS,
        "--format",
        "bc7",
        "--max-error",
        spec,
        "-o",
        plain.to_str().unwrap(),
    ]);
    let out = d.path().join("k.vdbc");
    let o = out.to_str().unwrap();
    let c = json(&[&["cook", "--json"][..], &clustered(spec, o)].concat());
    let k = &c["clustering"];
    assert!(k["clusters"].as_u64().unwrap() > 0, "{k}");
    // Members share centroids: fewer bricks go to the encoder than the pool holds.
    let b = &c["bricks"];
    assert!(
        b["after_clustering"].as_u64() < b["unique"].as_u64(),
        "clustering merged nothing: {b}"
    );
    assert_eq!(c0["bricks"]["after_clustering"], c0["bricks"]["unique"]);
    // Each channel within its own budget, as eval reads the written file against the sources.
    let e = eval_channels(o, &[FIRE]);
    for (name, b) in budgets {
        assert!(e[name] <= b, "{name}: {} over its budget {b}", e[name]);
    }
    // No centroid mixes grids: no more bricks are read by two channels than deduplication
    // alone shares.
    assert_eq!(
        shared_bricks(o),
        shared_bricks(plain.to_str().unwrap()),
        "a centroid is read by several channels"
    );
    // The same bytes at 1 and 2 threads.
    let one = d.path().join("one.vdbc");
    let (code, _, err) = run(&[
        &["--threads", "1", "cook"][..],
        &clustered(spec, one.to_str().unwrap()),
    ]
    .concat());
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::read(&one).unwrap(), std::fs::read(&out).unwrap());
}

#[test]
fn several_grids_fit_a_size_budget_with_one_share_of_each_range() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("s.vdbc");
    let o = out.to_str().unwrap();
    let lossless = gpu_bytes(&json(&["cook", "--json", FIRE, "--grids", GRIDS, "-o", o]));
    let limit = lossless / 5;
    for extra in [
        &[][..],
        &["--clusters", "16", "--variance-threshold", "100"][..],
    ] {
        let mut args = vec![
            "cook",
            "--json",
            FIRE,
            "--grids",
            GRIDS,
            "-o",
            o,
            "--max-bytes",
        ];
        let l = limit.to_string();
        args.push(&l);
        args.extend_from_slice(extra);
        let c = json(&args);
        assert!(
            gpu_bytes(&c) <= limit,
            "{extra:?}: {} > {limit}",
            gpu_bytes(&c)
        );
        let search = &c["max_bytes"];
        let t = search["fraction_of_range"].as_f64().unwrap();
        assert!(t > 0.0 && t < 1.0, "{search}");
        let e = eval_channels(o, &[FIRE]);
        for ch in c["channels"].as_array().unwrap() {
            let name = ch["name"].as_str().unwrap();
            let bound = ch["max_error"].as_f64().unwrap();
            assert_eq!(ch["max_error_source"], "max_bytes");
            // One share of the channel's range, the background included.
            let r = ch["value_range"].as_array().unwrap();
            let bg = ch["background"].as_f64().unwrap();
            let lo = r[0].as_f64().unwrap().min(bg);
            let hi = r[1].as_f64().unwrap().max(bg);
            let want = (hi - lo) * t;
            assert!(
                (bound - want).abs() <= 1e-6 * want,
                "{name}: bound {bound}, {t} of its range is {want}"
            );
            assert!(
                e[name] <= bound,
                "{extra:?} {name}: {} over {bound}",
                e[name]
            );
        }
    }
}

#[test]
fn one_grid_fits_a_size_budget_with_clustering() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("s.vdbc");
    let o = out.to_str().unwrap();
    let src = "fixtures/seq/smoke5";
    let lossless = gpu_bytes(&json(&["cook", "--json", src, "-o", o]));
    let limit = (lossless / 10).to_string();
    let c = json(&[
        "cook",
        "--json",
        src,
        "-o",
        o,
        "--max-bytes",
        &limit,
        "--clusters",
        "32",
        "--variance-threshold",
        "100",
    ]);
    assert!(gpu_bytes(&c) <= lossless / 10);
    assert!(c["clustering"]["clusters"].as_u64().unwrap() > 0, "{c}");
    let bound = c["max_error"].as_f64().unwrap();
    let e = json(&["eval", "--json", o, src]);
    assert!(e["max_abs"].as_f64().unwrap() <= bound);
}

#[test]
fn several_grids_cook_a_frame_range_exactly() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("r.vdbc");
    let o = out.to_str().unwrap();
    let c = json(&[
        "cook", "--json", FIRE, "--grids", GRIDS, "--frames", "2..3", "-o", o,
    ]);
    assert_eq!(c["frames"], 2);
    let e = json(&[
        "eval",
        "--json",
        o,
        "fixtures/seq/fire/fire.0002.vdb",
        "fixtures/seq/fire/fire.0003.vdb",
    ]);
    assert_eq!(e["max_abs"], 0.0, "{e}");
    assert_eq!(e["channels"].as_array().unwrap().len(), 3);
}

/// A project with the fire sequence and a manifest of several-grid entries.
fn fire_project(dir: &Path) -> std::path::PathBuf {
    let fire = dir.join("cache/fire");
    std::fs::create_dir_all(&fire).unwrap();
    for e in std::fs::read_dir(root().join(FIRE)).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "vdb") {
            std::fs::copy(&p, fire.join(p.file_name().unwrap())).unwrap();
        }
    }
    let m = dir.join("fire.toml");
    std::fs::write(
        &m,
        r#"[[asset]]
input = "cache/fire"
output = "out/fire.vdbc"
grids = "auto"
format = "bc7"
max-error = { density = 0.01, temperature = 5, flame = 0.02 }
clusters = 16
variance-threshold = 100
lod = "all"

[[asset]]
input = "cache/fire"
output = "out/fire_small.vdbc"
grids = ["density", "flame"]
max-bytes = "20KiB"
frames = "1..2"
"#,
    )
    .unwrap();
    m
}

fn manifest(m: &Path) -> (i32, Value, String) {
    let (code, out, err) = run(&["cook", "--json", "--manifest", m.to_str().unwrap()]);
    (code, serde_json::from_str(&out).unwrap_or(Value::Null), err)
}

#[test]
fn the_manifest_takes_every_option_and_matches_the_cli() {
    let d = tempfile::tempdir().unwrap();
    let m = fire_project(d.path());
    let (code, doc, err) = manifest(&m);
    assert_eq!(code, 0, "{err}");
    assert_eq!(doc["cooked"], 2, "{doc}");
    // The same asset as the CLI with the same flags.
    let cli = d.path().join("cli.vdbc");
    let (code, _, err) = run(&[
        "cook",
        d.path().join("cache/fire").to_str().unwrap(),
        "--grids",
        "auto",
        "--format",
        "bc7",
        "--max-error",
        "density=0.01,temperature=5,flame=0.02",
        "--clusters",
        "16",
        "--variance-threshold",
        "100",
        "--lod",
        "all",
        "-o",
        cli.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let from_manifest = std::fs::read(d.path().join("out/fire.vdbc")).unwrap();
    assert_eq!(std::fs::read(&cli).unwrap(), from_manifest);
    let a = Asset::from_bytes(&from_manifest).unwrap();
    assert_eq!(a.channel_count(), 3);
    assert!(a.header.lod_levels > 0);
    let small = Asset::load(d.path().join("out/fire_small.vdbc")).unwrap();
    assert_eq!((small.channel_count(), small.frame_count()), (2, 2));
    // A second run is all cache hits.
    let (code, doc, err) = manifest(&m);
    assert_eq!(code, 0, "{err}");
    assert_eq!(doc["cooked"], 0, "{doc}");
}

#[test]
fn a_damaged_cache_entry_is_cooked_again_not_served() {
    let d = tempfile::tempdir().unwrap();
    let m = fire_project(d.path());
    let (code, doc, err) = manifest(&m);
    assert_eq!(code, 0, "{err}");
    let good = std::fs::read(d.path().join("out/fire.vdbc")).unwrap();
    let key = doc["assets"][0]["key"].as_str().unwrap().to_string();
    let entry = d.path().join(format!(".vdbcook-cache/{key}.vdbc"));
    // A flipped byte in the middle, then a truncation.
    for damage in ["flip", "truncate"] {
        let mut bytes = std::fs::read(&entry).unwrap();
        match damage {
            "flip" => {
                let i = bytes.len() / 2;
                bytes[i] ^= 0x40;
            }
            _ => bytes.truncate(bytes.len() * 2 / 3),
        }
        std::fs::write(&entry, &bytes).unwrap();
        // The output too, so a served entry would show.
        std::fs::remove_file(d.path().join("out/fire.vdbc")).unwrap();
        let (code, doc, err) = manifest(&m);
        assert_eq!(code, 0, "{damage}: {err}");
        assert_eq!(doc["assets"][0]["status"], "cooked", "{damage}: {doc}");
        assert_eq!(doc["assets"][1]["status"], "cached", "{damage}: {doc}");
        assert!(err.contains("damaged"), "{damage}: no note: {err}");
        assert_eq!(
            std::fs::read(d.path().join("out/fire.vdbc")).unwrap(),
            good,
            "{damage}"
        );
        assert_eq!(
            std::fs::read(&entry).unwrap(),
            good,
            "{damage}: entry repaired"
        );
    }
}

#[test]
fn concurrent_runs_share_one_cache() {
    let d = tempfile::tempdir().unwrap();
    let m = fire_project(d.path());
    let cache = d.path().join("shared-cache");
    let spawn = |out: &str| {
        // Two projects' worth of outputs: each run writes its own outputs, one cache.
        let m2 = d.path().join(format!("{out}.toml"));
        let text = std::fs::read_to_string(&m)
            .unwrap()
            .replace("out/", &format!("{out}/"));
        std::fs::write(&m2, text).unwrap();
        std::process::Command::new(env!("CARGO_BIN_EXE_vdbcook"))
            .args([
                "cook",
                "--json",
                "--manifest",
                m2.to_str().unwrap(),
                "--cache-dir",
                cache.to_str().unwrap(),
            ])
            .output()
            .unwrap()
    };
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(|| spawn("a"));
        let b = s.spawn(|| spawn("b"));
        (a.join().unwrap(), b.join().unwrap())
    });
    for o in [&a, &b] {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    for name in ["fire.vdbc", "fire_small.vdbc"] {
        let x = std::fs::read(d.path().join("a").join(name)).unwrap();
        let y = std::fs::read(d.path().join("b").join(name)).unwrap();
        assert_eq!(x, y, "{name}");
        Asset::from_bytes(&x).unwrap();
    }
    // No temporary left behind, every entry whole.
    for e in std::fs::read_dir(&cache).unwrap() {
        let p = e.unwrap().path();
        let n = p.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!n.contains("partial"), "{n} left behind");
        if n.ends_with(".vdbc") {
            Asset::load(&p).unwrap();
        }
    }
}

/// Levels of several grids serve the light volume as a single grid's do: the lit render of the
/// fire cooked with three channels and `--lod all` is the lit render of its density grid cooked
/// alone with `--lod all`, on the CPU and the GPU (the light volume reads channel 0 of the
/// levels; the index of channel 1 or 2 would light another field).
#[test]
fn several_grids_with_levels_light_as_the_density_grid_alone() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n).to_string_lossy().into_owned();
    let (three, one) = (p("three.vdbc"), p("one.vdbc"));
    json(&[
        "cook", "--json", FIRE, "--grids", GRIDS, "--lod", "all", "-o", &three,
    ]);
    json(&[
        "cook", "--json", FIRE, "--grid", "density", "--lod", "all", "-o", &one,
    ]);
    for backend in ["cpu", "gpu"] {
        let mut images = Vec::new();
        for asset in [&three, &one] {
            let out = p(&format!("{backend}-{}.pfm", images.len()));
            let (code, _, err) = run(&[
                "render",
                asset,
                "--mode",
                "lit",
                "--backend",
                backend,
                "--width",
                "96",
                "--height",
                "54",
                // The density's light alone: the fire's default glow off.
                "--emission",
                "off",
                "-o",
                &out,
            ]);
            if backend == "gpu" && code != 0 && !common::gpu_required() {
                eprintln!("skipping the GPU: {err}");
                return;
            }
            assert_eq!(code, 0, "{err}");
            images.push(common::read_pfm(Path::new(&out)).2);
        }
        assert!(
            images[0].iter().any(|&v| v > 0.01),
            "{backend}: a black image"
        );
        assert_eq!(images[0], images[1], "{backend}");
    }
}
