//! Where the real VDB samples are, for every test that reads them (included by path from the
//! reader's and the cooker's tests, so there is one rule): `$VDBCOOK_SAMPLES` when set (it must
//! exist), else `../shared/samples` beside the repository. When neither is there, a developer's
//! run skips those tests and says so; under CI (`CI` set and not `false`/`0`, or
//! `VDBCOOK_REQUIRE_SAMPLES=1`) it fails instead, so a skipped sample test cannot pass silently.

use std::path::{Path, PathBuf};

/// Whether a missing sample is a failure (CI) rather than a skip.
pub fn samples_required() -> bool {
    let on = |k: &str| std::env::var(k).is_ok_and(|v| !v.is_empty() && v != "0" && v != "false");
    on("CI") || on("VDBCOOK_REQUIRE_SAMPLES")
}

/// The samples folder (see the file's docs); `None` only where skipping is allowed.
pub fn samples_dir(repo_root: &Path) -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("VDBCOOK_SAMPLES") {
        let p = PathBuf::from(p);
        assert!(
            p.is_dir(),
            "VDBCOOK_SAMPLES={} is not a folder",
            p.display()
        );
        return Some(p);
    }
    let p = repo_root.join("../shared/samples");
    if p.is_dir() {
        return Some(p);
    }
    assert!(
        !samples_required(),
        "the real samples are missing ({} is not there; set VDBCOOK_SAMPLES): under CI the \
         sample tests must run",
        p.display()
    );
    eprintln!(
        "skipping: no samples ({} is not there; set VDBCOOK_SAMPLES)",
        p.display()
    );
    None
}

/// `name` inside the samples folder, which must exist there when samples are required.
pub fn sample(dir: &Path, name: &str) -> Option<PathBuf> {
    let p = dir.join(name);
    if p.exists() {
        return Some(p);
    }
    assert!(!samples_required(), "sample {} is missing", p.display());
    eprintln!("skipping {}: not in the samples folder", p.display());
    None
}
