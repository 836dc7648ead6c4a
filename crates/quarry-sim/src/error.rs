//! The crate's error type.

use quarry_core::CoreError;
use thiserror::Error;

/// Errors of quarry-sim (scenario configuration and dataset readers).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SimError {
    /// A shared error kind (bad parameter, non-finite value, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A dataset file that could not be read.
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
}
