//! The crate's error type.

use quarry_core::CoreError;
use thiserror::Error;

/// Errors of quarry-sim (scenario configuration, and writing ground truth).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SimError {
    /// A shared error kind (bad parameter, non-finite value, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A file that could not be written (the ground-truth CSV writer).
    #[error("cannot write {path}: {reason}")]
    Io {
        /// The path.
        path: String,
        /// What went wrong.
        reason: String,
    },
}
