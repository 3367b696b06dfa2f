//! How the CLI reports failure: one line on stderr naming the file, and under `--json` one JSON
//! document `{"error": {...}}` on stdout, then a non-zero exit code (1 for bad input, 2 for a
//! flag out of range or a combination of flags that cannot do what it says).

use vdbcook_vdb::{ErrorKind, VdbError};

/// Any failure a subcommand can end with.
#[derive(Debug)]
pub enum CliError {
    Vdb(VdbError),
    /// A failure that is not about one input file (e.g. an internal check).
    Other(String),
    /// A flag out of its range, or flags that contradict each other (kind `usage`, exit 2, as
    /// the argument parser's own usage errors).
    Usage(String),
}

impl From<VdbError> for CliError {
    fn from(e: VdbError) -> Self {
        CliError::Vdb(e)
    }
}

impl From<vdbcook_cook::CookError> for CliError {
    fn from(e: vdbcook_cook::CookError) -> Self {
        use vdbcook_cook::CookError;
        match e {
            CookError::Input(v) => CliError::Vdb(v),
            CookError::Options(m) => CliError::Usage(m),
            CookError::Internal(m) => CliError::Other(m),
        }
    }
}

impl std::fmt::Display for CliError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CliError::Vdb(e) => e.fmt(f),
            CliError::Other(m) | CliError::Usage(m) => f.write_str(m),
        }
    }
}

pub fn fail(json: bool, e: &CliError) -> ! {
    eprintln!("error: {e}");
    if json {
        let (kind, file, offset) = match e {
            CliError::Vdb(v) => (
                match v.kind {
                    ErrorKind::Io => "io",
                    ErrorKind::Corrupt => "corrupt",
                    ErrorKind::Unsupported => "unsupported",
                    ErrorKind::GridSelection => "grid_selection",
                    ErrorKind::Sequence => "sequence",
                },
                Some(v.path.display().to_string()),
                v.offset,
            ),
            CliError::Other(_) => ("other", None, None),
            CliError::Usage(_) => ("usage", None, None),
        };
        let doc = serde_json::json!({"error": {"message": e.to_string(), "kind": kind, "file": file, "offset": offset}});
        println!("{doc}");
    }
    std::process::exit(if matches!(e, CliError::Usage(_)) {
        2
    } else {
        1
    });
}
