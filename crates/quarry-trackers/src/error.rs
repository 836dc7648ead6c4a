//! The crate's error type.

use quarry_core::CoreError;
use thiserror::Error;

/// Errors of quarry-trackers. Module-level errors of the building blocks become variants.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TrackerError {
    /// A shared error kind (bad parameter, non-finite value, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A tracker configuration that cannot be used.
    #[error("invalid configuration: {0}")]
    Config(String),
}
