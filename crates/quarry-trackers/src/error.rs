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
    /// Extrinsic calibration failed for one scanner (spec 003 §2.3): e.g. quarry-cloud's
    /// `CalibrationInsufficient` (overlap or inlier RMS out of bounds), or no usable background.
    #[error("calibration of scanner {scanner} failed: {reason}")]
    Calibration {
        /// The scanner's name and sensor id.
        scanner: String,
        /// Why.
        reason: String,
        /// The quarry-cloud error, when there is one (its text is in `reason`).
        cloud: Option<quarry_cloud::CloudError>,
    },
}
