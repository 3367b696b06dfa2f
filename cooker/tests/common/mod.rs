//! Shared by the binary's integration tests: where the repository is, running `vdbcook` from it
//! the way a script does (exit code, stdout, stderr), the samples rule, cooking the default
//! smoke, reading PNGs and PFMs, and whether a GPU test may skip.

#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

use serde_json::Value;

/// The repository root (the test kit's).
pub fn root() -> PathBuf {
    vdbcook_testkit::repo_root()
}

#[path = "../../../crates/vdb/tests/support/samples.rs"]
mod samples_support;

/// The real samples (`$VDBCOOK_SAMPLES` or `../shared/samples`; a failure under CI when missing).
#[allow(dead_code)]
pub fn samples() -> Option<PathBuf> {
    samples_support::samples_dir(&root())
}

/// One sample as a path string, `None` where samples may be skipped.
#[allow(dead_code)]
pub fn sample(name: &str) -> Option<String> {
    let dir = samples()?;
    samples_support::sample(&dir, name).map(|p| p.to_string_lossy().into_owned())
}

/// Runs `vdbcook ARGS` in the repository root: (exit code, stdout, stderr).
pub fn vdbcook(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
        .args(args)
        .current_dir(root())
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// Runs `vdbcook ARGS`, which must succeed and print one JSON document.
pub fn json(args: &[&str]) -> Value {
    let (code, out, err) = vdbcook(args);
    assert_eq!(code, 0, "vdbcook {args:?} failed: {err}");
    serde_json::from_str(&out)
        .unwrap_or_else(|e| panic!("{args:?}: not one JSON document ({e}): {out}"))
}

/// GPU bytes (topology + atlas) of a `cook --json` document.
pub fn gpu_bytes(c: &Value) -> u64 {
    c["bytes"]["topology"].as_u64().unwrap() + c["bytes"]["atlas"].as_u64().unwrap()
}

/// Whether a GPU test must run (CI sets VDBCOOK_REQUIRE_GPU=1) or may skip when there is none.
pub fn gpu_required() -> bool {
    std::env::var_os("VDBCOOK_REQUIRE_GPU").is_some_and(|v| v != "0")
}

/// Cooks `fixtures/seq/smoke5` (f32) into `dir/smoke5.vdbc`; its path.
pub fn cook_smoke(dir: &std::path::Path) -> String {
    let asset = dir.join("smoke5.vdbc").display().to_string();
    let (code, _, err) = vdbcook(&["cook", "fixtures/seq/smoke5", "-o", &asset]);
    assert_eq!(code, 0, "{err}");
    asset
}

/// Width, height and 8-bit RGBA pixels of a PNG.
pub fn read_png(path: &std::path::Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// A colour PFM as written by `render`: width, height, RGB floats with row 0 at the top.
pub fn read_pfm(path: &std::path::Path) -> (u32, u32, Vec<f32>) {
    let b = std::fs::read(path).unwrap();
    let mut lines = b.splitn(4, |&c| c == b'\n');
    assert_eq!(lines.next().unwrap(), b"PF");
    let dims = std::str::from_utf8(lines.next().unwrap()).unwrap();
    let (w, h) = dims.split_once(' ').unwrap();
    let (w, h): (u32, u32) = (w.parse().unwrap(), h.parse().unwrap());
    let scale: f32 = std::str::from_utf8(lines.next().unwrap())
        .unwrap()
        .parse()
        .unwrap();
    assert!(scale < 0.0, "little-endian");
    let data = lines.next().unwrap();
    assert_eq!(data.len(), (w * h * 12) as usize);
    let row = 3 * w as usize;
    let mut out = vec![0.0; row * h as usize];
    for (k, c) in data.chunks_exact(4).enumerate() {
        let (y, x) = (k / row, k % row);
        out[(h as usize - 1 - y) * row + x] = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    }
    (w, h, out)
}
