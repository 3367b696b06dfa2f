//! `vdbcook cook --manifest` (issue 17): a manifest of three assets, two sharing inputs, cooks;
//! every output is byte-identical to a single `vdbcook cook` with the same options; a second run
//! cooks nothing; changing one input's content recooks exactly the assets that read it; changing
//! one entry's options recooks only it; a copied project with a shared cache folder is all cache
//! hits (keys do not depend on where the files are); bad manifests name their line and write
//! nothing.

mod common;

use std::path::{Path, PathBuf};

use common::{root, vdbcook};
use serde_json::Value;

fn manifest_run(manifest: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["cook", "--json", "--manifest", manifest.to_str().unwrap()];
    args.extend(extra);
    let (code, out, err) = vdbcook(&args);
    assert_eq!(code, 0, "{err}");
    serde_json::from_str(&out).unwrap()
}

/// A project folder: `cache/smoke5/` (5 frames), `cache/centres.vdb`, and the manifest.
fn project(dir: &Path, third_format: &str) -> PathBuf {
    let smoke = dir.join("cache/smoke5");
    std::fs::create_dir_all(&smoke).unwrap();
    for e in std::fs::read_dir(root().join("fixtures/seq/smoke5")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "vdb") {
            std::fs::copy(&p, smoke.join(p.file_name().unwrap())).unwrap();
        }
    }
    std::fs::copy(
        root().join("fixtures/vdb/centres.vdb"),
        dir.join("cache/centres.vdb"),
    )
    .unwrap();
    let m = dir.join("volumes.toml");
    std::fs::write(
        &m,
        format!(
            r#"# Three assets; the first two read the same frames.
[[asset]]
input = "cache/smoke5/smoke.####.vdb"
output = "out/smoke.vdbc"
format = "bc7"
no-packed = true

[[asset]]
input = "cache/smoke5"
output = "out/smoke_mid.vdbc"
format = "f16"
frames = "2..4"

[[asset]]
input = "cache/centres.vdb"
output = "out/ball.vdbc"
format = "{third_format}"
"#
        ),
    )
    .unwrap();
    m
}

fn statuses(doc: &Value) -> Vec<String> {
    doc["assets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["status"].as_str().unwrap().to_string())
        .collect()
}

/// The bytes `vdbcook cook` writes for these arguments.
fn single_cook(dir: &Path, args: &[&str]) -> Vec<u8> {
    let out = dir.join("single.vdbc");
    let mut a = vec!["cook"];
    a.extend(args);
    a.extend(["-o", out.to_str().unwrap()]);
    let (code, _, err) = vdbcook(&a);
    assert_eq!(code, 0, "{err}");
    std::fs::read(out).unwrap()
}

fn check_outputs_match_single_cooks(dir: &Path) {
    let s = |p: &str| dir.join(p).to_str().unwrap().to_string();
    let want = [
        (
            "out/smoke.vdbc",
            single_cook(
                dir,
                &[
                    &s("cache/smoke5/smoke.####.vdb"),
                    "--format",
                    "bc7",
                    "--no-packed",
                ],
            ),
        ),
        (
            "out/smoke_mid.vdbc",
            single_cook(
                dir,
                &[&s("cache/smoke5"), "--format", "f16", "--frames", "2..4"],
            ),
        ),
    ];
    for (out, bytes) in want {
        assert!(
            std::fs::read(dir.join(out)).unwrap() == bytes,
            "{out} differs from a single cook"
        );
    }
}

#[test]
fn a_manifest_cooks_caches_and_recooks_only_what_changed() {
    let d = tempfile::tempdir().unwrap();
    let m = project(d.path(), "f32");
    let first = manifest_run(&m, &[]);
    assert_eq!(statuses(&first), ["cooked", "cooked", "cooked"]);
    assert_eq!(first["cooked"], 3);
    check_outputs_match_single_cooks(d.path());
    let mid: Value = first["assets"][1]["cook"].clone();
    assert_eq!(mid["frames"], 3, "frames 2..4");

    // Unchanged: nothing is cooked, the outputs stay.
    let before: Vec<Vec<u8>> = ["smoke", "smoke_mid", "ball"]
        .iter()
        .map(|n| std::fs::read(d.path().join(format!("out/{n}.vdbc"))).unwrap())
        .collect();
    let second = manifest_run(&m, &[]);
    assert_eq!(statuses(&second), ["cached", "cached", "cached"]);
    for (i, a) in second["assets"].as_array().unwrap().iter().enumerate() {
        assert_eq!(a["key"], first["assets"][i]["key"]);
        assert_eq!(
            std::fs::read(a["output"].as_str().unwrap()).unwrap(),
            before[i]
        );
    }

    // A deleted output comes back from the cache, byte for byte.
    std::fs::remove_file(d.path().join("out/ball.vdbc")).unwrap();
    let third = manifest_run(&m, &[]);
    assert_eq!(statuses(&third), ["cached", "cached", "cached"]);
    assert_eq!(
        std::fs::read(d.path().join("out/ball.vdbc")).unwrap(),
        before[2]
    );

    // New content in frame 3 (frame 5's bytes): both smoke assets read it, the ball does not.
    let f3 = d.path().join("cache/smoke5/smoke.0003.vdb");
    std::fs::copy(d.path().join("cache/smoke5/smoke.0005.vdb"), &f3).unwrap();
    let fourth = manifest_run(&m, &[]);
    assert_eq!(statuses(&fourth), ["cooked", "cooked", "cached"]);
    check_outputs_match_single_cooks(d.path());

    // One entry's format changes: only it recooks.
    std::fs::write(
        &m,
        std::fs::read_to_string(&m)
            .unwrap()
            .replace("format = \"f32\"", "format = \"f16\""),
    )
    .unwrap();
    let fifth = manifest_run(&m, &[]);
    assert_eq!(statuses(&fifth), ["cached", "cached", "cooked"]);
    assert_ne!(fifth["assets"][2]["key"], fourth["assets"][2]["key"]);
}

#[test]
fn a_shared_cache_folder_serves_a_copy_of_the_project_elsewhere() {
    let (a, b, cache) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    let c = cache.path().to_str().unwrap();
    let ma = project(a.path(), "bc4");
    let first = manifest_run(&ma, &["--cache-dir", c]);
    assert_eq!(first["cooked"], 3);
    // The same project checked out somewhere else (another machine of a build farm).
    let mb = project(b.path(), "bc4");
    let second = manifest_run(&mb, &["--cache-dir", c]);
    assert_eq!(statuses(&second), ["cached", "cached", "cached"]);
    for n in ["smoke", "smoke_mid", "ball"] {
        let p = format!("out/{n}.vdbc");
        assert_eq!(
            std::fs::read(a.path().join(&p)).unwrap(),
            std::fs::read(b.path().join(&p)).unwrap()
        );
    }
}

#[test]
fn bad_manifests_name_their_line_and_write_nothing() {
    let d = tempfile::tempdir().unwrap();
    project(d.path(), "f32");
    let bad = d.path().join("bad.toml");
    let cases: [(&str, &str, &str); 6] = [
        (
            "[[asset]]\ninput = \"cache/smoke5\"\noutput = \"out/a.vdbc\"\ncolour = \"red\"\n",
            "bad.toml:4",
            "unknown field `colour`",
        ),
        (
            "[[asset]]\ninput = \"cache/smoke5\"\noutput = \"out/a.vdbc\"\n\n[[asset]]\ninput = \"cache/none.####.vdb\"\noutput = \"out/b.vdbc\"\n",
            "bad.toml:5",
            "no files match",
        ),
        (
            "[[asset]]\ninput = \"cache/smoke5\"\noutput = \"out/a.vdbc\"\n\n[[asset]]\ninput = \"cache/centres.vdb\"\noutput = \"out/./a.vdbc\"\n",
            "bad.toml:5",
            "both write",
        ),
        (
            "[[asset]]\ninput = \"cache/smoke5\"\noutput = \"cache/centres.vdb\"\n\n[[asset]]\ninput = \"cache/centres.vdb\"\noutput = \"out/c.vdbc\"\n",
            "bad.toml:1",
            "outputs cannot be inputs",
        ),
        (
            "[[asset]]\ninput = \"cache/smoke5\"\noutput = \"out/a.vdbc\"\nformat = \"bc9\"\n",
            "bad.toml:1",
            "format 'bc9'",
        ),
        ("[[asset]\n", "bad.toml:1", ""),
    ];
    for (text, at, says) in cases {
        std::fs::write(&bad, text).unwrap();
        let (code, _, err) = vdbcook(&["cook", "--manifest", bad.to_str().unwrap()]);
        assert_eq!(code, 2, "{text}\n{err}");
        assert!(err.contains(at) && err.contains(says), "{text}\n{err}");
        assert!(!d.path().join("out").exists(), "{text}: wrote outputs");
        assert!(
            !d.path().join(".vdbcook-cache").exists(),
            "{text}: made a cache"
        );
    }
    // -o with --manifest, and --frames with --manifest, are refused.
    std::fs::write(
        &bad,
        "[[asset]]\ninput = \"cache/smoke5\"\noutput = \"out/a.vdbc\"\n",
    )
    .unwrap();
    let b = bad.to_str().unwrap();
    assert_eq!(vdbcook(&["cook", "--manifest", b, "-o", "x.vdbc"]).0, 2);
    assert_eq!(vdbcook(&["cook", "--manifest", b, "--frames", "1..2"]).0, 2);
}

#[test]
fn frames_select_by_the_numbers_in_the_file_names() {
    let d = tempfile::tempdir().unwrap();
    let src = root().join("fixtures/seq/smoke5");
    let s = src.to_str().unwrap();
    let out = d.path().join("f.vdbc");
    let o = out.to_str().unwrap();
    for (spec, n) in [("2..4", 3), ("4..", 2), ("..1", 1), ("3..3", 1)] {
        let (code, stdout, err) = vdbcook(&["cook", "--json", s, "-o", o, "--frames", spec]);
        assert_eq!(code, 0, "{spec}: {err}");
        let doc: Value = serde_json::from_str(&stdout).unwrap();
        assert_eq!(doc["frames"], n, "{spec}");
        let info: Value = serde_json::from_str(&vdbcook(&["info", "--json", o]).1).unwrap();
        let first = info["frames"][0]["number"].as_i64().unwrap();
        assert_eq!(
            first,
            spec.split("..").next().unwrap().parse().unwrap_or(1),
            "{spec}"
        );
    }
    for bad in ["9..12", "4..2", "x..3", "3"] {
        let (code, _, err) = vdbcook(&["cook", s, "-o", o, "--frames", bad]);
        assert_eq!(code, 2, "{bad}: {err}");
        assert!(err.contains("--frames"), "{bad}: {err}");
    }
}
