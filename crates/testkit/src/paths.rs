//! Where the repository is, for tests that read `fixtures/` or run scripts from the root
//! (formerly spelled out per test crate from its own `CARGO_MANIFEST_DIR`).

use std::path::{Path, PathBuf};

/// The repository root (canonical).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("repo root")
}

/// `fixtures/` under the repository root.
pub fn fixtures() -> PathBuf {
    repo_root().join("fixtures")
}
