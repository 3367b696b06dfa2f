//! One error type for everything the reader can refuse, so every message names the file and,
//! where it helps, the byte offset at which the problem was found.

use std::fmt;
use std::path::{Path, PathBuf};

/// What kind of failure this is; the CLI maps kinds to messages and tests match on them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The file could not be opened or read.
    Io,
    /// The bytes are not a valid VDB file (truncated, corrupt, absurd sizes).
    Corrupt,
    /// A valid file that uses something vdbcook does not read (old version, frustum map, ...).
    Unsupported,
    /// The requested grid does not exist or is not a float grid.
    GridSelection,
    /// Problems with a frame sequence (gaps, mismatched transforms, no files).
    Sequence,
}

/// An error with the file it concerns and, for format errors, the byte offset.
#[derive(Debug, Clone)]
pub struct VdbError {
    pub kind: ErrorKind,
    pub path: PathBuf,
    pub offset: Option<u64>,
    pub message: String,
}

impl VdbError {
    pub fn new(kind: ErrorKind, path: &Path, message: impl Into<String>) -> Self {
        VdbError {
            kind,
            path: path.to_path_buf(),
            offset: None,
            message: message.into(),
        }
    }

    pub(crate) fn from_parse(path: &Path, e: ParseError) -> Self {
        VdbError {
            kind: e.kind,
            path: path.to_path_buf(),
            offset: Some(e.offset),
            message: e.message,
        }
    }
}

impl fmt::Display for VdbError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)?;
        if let Some(o) = self.offset {
            write!(f, " (at byte {o})")?;
        }
        Ok(())
    }
}

impl std::error::Error for VdbError {}

/// A format error found while parsing bytes, before the file path is attached.
#[derive(Debug, Clone)]
pub(crate) struct ParseError {
    pub kind: ErrorKind,
    pub offset: u64,
    pub message: String,
}

impl ParseError {
    pub fn corrupt(offset: u64, message: impl Into<String>) -> Self {
        ParseError {
            kind: ErrorKind::Corrupt,
            offset,
            message: message.into(),
        }
    }
    pub fn unsupported(offset: u64, message: impl Into<String>) -> Self {
        ParseError {
            kind: ErrorKind::Unsupported,
            offset,
            message: message.into(),
        }
    }
}

pub(crate) type PResult<T> = Result<T, ParseError>;
