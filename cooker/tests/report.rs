//! `vdbcook report` as a user runs it, checked against independent paths: each row's sizes and
//! voxel errors against `vdbcook cook` + `vdbcook eval` run separately (eval reads the written
//! file and compares it with the source voxel by voxel), the f32 row exact, every file written
//! and readable (PNG decoded, CSV rows, Markdown embedding the pictures), peers skipped with a
//! note when their tools are missing, and a failure leaving no folder behind.

mod common;

use std::path::Path;
use std::process::Command;

use common::{json, root, vdbcook};
use serde_json::Value;

const KEYS: [&str; 13] = [
    "format",
    "clusters",
    "max_error",
    "bytes_gpu",
    "bytes_file",
    "bits_per_active_voxel",
    "rmse",
    "psnr_db",
    "max_abs",
    "image_rmse",
    "cook_seconds",
    "trace_ms_cpu",
    "trace_ms_gpu",
];

fn png_size(path: &Path) -> (u32, u32) {
    let d = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = d.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    // Not blank: charts and renders have ink.
    let px = &buf[..info.buffer_size()];
    assert!(px.iter().any(|&v| v < 100), "{}: blank", path.display());
    (info.width, info.height)
}

fn row<'a>(doc: &'a Value, label: &str) -> &'a Value {
    doc["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["label"] == label)
        .unwrap_or_else(|| panic!("no row {label}"))
}

#[test]
fn quick_report_rows_agree_with_separate_cook_and_eval() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let doc = json(&[
        "report",
        "fixtures/seq/smoke5",
        "-o",
        out.to_str().unwrap(),
        "--quick",
        "--json",
        "--no-peers",
        "--no-gpu",
    ]);
    let rows = doc["rows"].as_array().unwrap();
    for r in rows {
        for k in KEYS {
            assert!(r.get(k).is_some(), "row lacks {k}: {r}");
        }
        assert!(r["trace_ms_cpu"].as_f64().unwrap() > 0.0);
        assert!(r["trace_ms_gpu"].is_null(), "--no-gpu");
    }
    let formats: Vec<&str> = rows.iter().filter_map(|r| r["format"].as_str()).collect();
    for f in ["f32", "f16", "unorm8", "bc4", "bc7"] {
        assert!(formats.contains(&f), "{f} missing: {formats:?}");
    }
    let f32r = row(&doc, "f32");
    assert_eq!(f32r["rmse"], 0.0);
    assert_eq!(f32r["max_abs"], 0.0);
    assert_eq!(f32r["image_rmse"], 0.0, "the reference against itself");
    assert!(row(&doc, "bc7")["image_rmse"].as_f64().unwrap() > 0.0);

    // Each format row against an independent cook written to disk and evaluated from the file
    // (a format's row is that format under its guard, without packed bricks).
    for f in ["f16", "bc4", "bc7"] {
        let asset = dir.path().join(format!("{f}.vdbc"));
        let a = asset.to_str().unwrap();
        let (code, _, err) = vdbcook(&[
            "cook",
            "fixtures/seq/smoke5",
            "-o",
            a,
            "--format",
            f,
            "--no-packed",
        ]);
        assert_eq!(code, 0, "{err}");
        let ev = json(&["eval", a, "fixtures/seq/smoke5", "--json"]);
        let r = row(&doc, f);
        let file_len = std::fs::metadata(&asset).unwrap().len();
        assert_eq!(r["bytes_file"].as_u64().unwrap(), file_len, "{f} bytes");
        let (rmse, e_rmse) = (r["rmse"].as_f64().unwrap(), ev["rmse"].as_f64().unwrap());
        assert!(
            (rmse - e_rmse).abs() <= 1e-9 + 1e-6 * e_rmse,
            "{f}: report rmse {rmse} vs eval {e_rmse}"
        );
        assert_eq!(r["max_abs"].as_f64(), ev["max_abs"].as_f64(), "{f} max_abs");
    }
    // The max-error row keeps its bound (E is a fraction of the value range).
    let e = rows.iter().find(|r| !r["max_error"].is_null()).unwrap();
    assert!(e["max_abs"].as_f64().unwrap() <= e["max_error"].as_f64().unwrap() * (1.0 + 1e-6));

    // The files.
    for png in [
        "size_vs_error.png",
        "cook_time_vs_error.png",
        "trace_time_vs_error.png",
        "renders.png",
    ] {
        let (w, h) = png_size(&out.join(png));
        assert!(w >= 300 && h >= 100, "{png}: {w}x{h}");
    }
    let csv = std::fs::read_to_string(out.join("report.csv")).unwrap();
    assert_eq!(
        csv.lines().count(),
        rows.len() + 1,
        "a header and a line per row"
    );
    assert!(csv.starts_with("label,format,clusters,"));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for png in [
        "size_vs_error.png",
        "renders.png",
        "trace_time_vs_error.png",
    ] {
        assert!(md.contains(&format!("({png})")), "report.md embeds {png}");
    }
    let on_disk: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(on_disk["rows"], doc["rows"]);
    assert!(doc["notes"]
        .as_array()
        .unwrap()
        .iter()
        .any(|n| n.as_str().unwrap().contains("--no-peers")));
}

#[test]
fn missing_peers_and_gpu_are_notes_not_failures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    // A PATH without nanovdb_convert or vdb_render.
    let o = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
        .args([
            "report",
            "fixtures/seq/smoke5/smoke.0002.vdb",
            "-o",
            out.to_str().unwrap(),
            "--quick",
            "--json",
            "--no-gpu",
            "--tolerances",
            "0.05",
            "--width",
            "64",
            "--height",
            "48",
        ])
        .env("PATH", dir.path())
        .current_dir(root())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: Value = serde_json::from_slice(&o.stdout).unwrap();
    let notes: Vec<&str> = doc["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    assert!(
        notes
            .iter()
            .any(|n| n.contains("nanovdb_convert not found")),
        "{notes:?}"
    );
    assert!(
        notes.iter().any(|n| n.starts_with("vdb_render: skipped")),
        "{notes:?}"
    );
    assert_eq!(doc["peers"].as_array().unwrap().len(), 0);
    assert_eq!(doc["meta"]["render"]["width"], 64);
    assert_eq!(doc["meta"]["tolerances"][0], 0.05);
}

#[test]
fn a_failing_report_leaves_no_folder_and_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let o = out.to_str().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (&["fixtures/missing.vdb"], "missing.vdb"),
        (&["fixtures/seq/smoke5", "--frame", "9"], "--frame 9"),
        (
            &["fixtures/seq/smoke5", "--tolerances", "0"],
            "--tolerances",
        ),
        (&["fixtures/seq/smoke5", "--width", "0"], "image 0x"),
    ];
    for (extra, want) in cases {
        let mut args = vec!["report", "-o", o, "--quick", "--no-gpu", "--no-peers"];
        args.extend_from_slice(extra);
        let (code, _, err) = vdbcook(&args);
        assert_eq!(code, 1, "{extra:?}");
        assert!(err.contains(want), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?}: left {o} behind");
    }
}

#[test]
fn gpu_trace_times_come_with_an_adapter() {
    if std::env::var_os("VDBCOOK_REQUIRE_GPU").is_none_or(|v| v == "0") {
        eprintln!("skipping: set VDBCOOK_REQUIRE_GPU=1 to require the GPU column");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let doc = json(&[
        "report",
        "fixtures/seq/smoke5/smoke.0002.vdb",
        "-o",
        out.to_str().unwrap(),
        "--quick",
        "--json",
        "--no-peers",
        "--width",
        "64",
        "--height",
        "48",
    ]);
    assert!(doc["meta"]["gpu"].is_string(), "{}", doc["meta"]);
    for r in doc["rows"].as_array().unwrap() {
        assert!(r["trace_ms_gpu"].as_f64().unwrap() > 0.0, "{r}");
        assert!(r["gpu_upload_bytes"].as_u64().unwrap() > 0, "{r}");
    }
}
