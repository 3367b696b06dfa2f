//! Shared by the binary's integration tests: where the repository is, and running `vdbcook`
//! from it the way a script does (exit code, stdout, stderr).

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
