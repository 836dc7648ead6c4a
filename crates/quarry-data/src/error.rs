//! The crate's error type.

use quarry_core::CoreError;
use thiserror::Error;

/// Errors of quarry-data: a file that cannot be read, or a malformed line in it.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum DataError {
    /// A shared error kind (bad parameter, non-finite value, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A dataset file that could not be read (or that lacks what the reader needs).
    #[error("cannot read {path}: {reason}")]
    Io {
        /// The path.
        path: String,
        /// What went wrong.
        reason: String,
    },
    /// A malformed line in a dataset file.
    #[error("{path}:{line}: {reason}")]
    Parse {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// What was wrong.
        reason: String,
    },
    /// A malformed recorded-scan CSV (or its geometry file).
    #[error("scan CSV line {line}: {reason}")]
    Csv {
        /// 1-based line number (the header is line 1; 0 when not tied to a line).
        line: u64,
        /// What was wrong.
        reason: String,
    },
}

impl From<std::io::Error> for DataError {
    fn from(e: std::io::Error) -> Self {
        Self::Io {
            path: String::new(),
            reason: e.to_string(),
        }
    }
}

/// Shorthand result type.
pub type Result<T, E = DataError> = std::result::Result<T, E>;
