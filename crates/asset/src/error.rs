//! Why an asset was refused: every message says which check failed and the numbers involved.

use std::fmt;

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AssetError(pub String);

impl fmt::Display for AssetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for AssetError {}

pub(crate) fn bad<T>(m: impl Into<String>) -> Result<T, AssetError> {
    Err(AssetError(m.into()))
}
