//! How a cook fails: [`CookError`], whose kind says whose fault it is — an input file (with the
//! file and, where known, the byte offset), the options (out of range or contradicting each
//! other), or the cooker itself (an internal check). The CLI maps the kinds to its exit codes.

use std::path::Path;

use vdbcook_vdb::{ErrorKind, VdbError};

/// Any failure of a cook.
#[derive(Debug)]
pub enum CookError {
    /// An input file is missing, unreadable, corrupt, unsupported or does not fit the sequence.
    Input(VdbError),
    /// An option out of its range, or options that contradict each other.
    Options(String),
    /// An internal check failed (a bug: the message says which).
    Internal(String),
}

impl From<VdbError> for CookError {
    fn from(e: VdbError) -> Self {
        CookError::Input(e)
    }
}

impl std::fmt::Display for CookError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CookError::Input(e) => e.fmt(f),
            CookError::Options(m) | CookError::Internal(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for CookError {}

/// An input error of `kind` about `path`.
pub(crate) fn input(path: &Path, kind: ErrorKind, m: impl Into<String>) -> CookError {
    CookError::Input(VdbError::new(kind, path, m))
}
