//! The crate's error type.

use quarry_core::{CoreError, SensorId};
use thiserror::Error;

/// Everything that can go wrong in quarry-cloud.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum CloudError {
    /// A shared error kind (non-finite input, empty input, wrong size, bad parameter, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// Fewer points than an algorithm needs (e.g. `model→data` ICP with a cluster smaller than
    /// the model, spec 003 §2.6).
    #[error("too few points in {what}: need {needed}, got {got}")]
    TooFewPoints {
        /// Which input.
        what: &'static str,
        /// How many are needed.
        needed: usize,
        /// How many were given.
        got: usize,
    },
    /// Reading a file failed.
    #[error("I/O error: {0}")]
    Io(String),
    /// Background calibration could not register a scanner well enough (spec 003 §2.3 step 4).
    #[error(
        "calibration of sensor {sensor:?} insufficient: overlap {overlap:.3} (need >= {min_overlap}), inlier RMS {rms:.4} m (need <= {max_rms})"
    )]
    CalibrationInsufficient {
        /// The scanner that failed.
        sensor: SensorId,
        /// Fraction of its background points within the final correspondence distance.
        overlap: f64,
        /// Required overlap.
        min_overlap: f64,
        /// Inlier RMS, metres.
        rms: f64,
        /// Required RMS bound, metres.
        max_rms: f64,
    },
}

impl From<std::io::Error> for CloudError {
    fn from(e: std::io::Error) -> Self {
        Self::Io(e.to_string())
    }
}

impl From<CloudError> for CoreError {
    /// Maps a [`CloudError`] onto the shared kinds so the quarry-core traits can return it:
    /// core errors pass through, `TooFewPoints` becomes a dimension mismatch, the rest become
    /// [`CoreError::Numerical`] with the message.
    fn from(e: CloudError) -> Self {
        match e {
            CloudError::Core(c) => c,
            CloudError::TooFewPoints { what, needed, got } => CoreError::DimensionMismatch {
                what,
                expected: needed,
                got,
            },
            other => CoreError::numerical("quarry-cloud", other.to_string()),
        }
    }
}

/// Shorthand result type.
pub type Result<T, E = CloudError> = std::result::Result<T, E>;
