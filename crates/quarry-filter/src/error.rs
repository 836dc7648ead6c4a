//! The crate's error type.

use quarry_core::CoreError;
use thiserror::Error;

/// Everything that can go wrong in quarry-filter.
///
/// Every fallible function leaves its inputs untouched when it returns an error: a failed update
/// never poisons a filter's state.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum FilterError {
    /// One of the shared error kinds (non-finite input, wrong size, invalid parameter, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A measurement holds a NaN or an infinity.
    #[error("non-finite value in the measurement")]
    NonFiniteMeasurement,
    /// The innovation covariance `S = H P Hᵀ + R` is not finite or cannot be Cholesky-factored.
    #[error("innovation covariance S = H P H^T + R is not positive definite (or not finite)")]
    InnovationNotPositiveDefinite,
    /// The filter produced a non-finite state or covariance (the model returned NaN or infinity,
    /// or the numbers overflowed); the state was left unchanged.
    #[error("non-finite result in {what}")]
    NonFiniteResult {
        /// Which step produced it.
        what: &'static str,
    },
    /// The time step is negative or not finite.
    #[error("invalid time step dt = {dt} (must be finite and >= 0)")]
    InvalidTimeStep {
        /// The offending value.
        dt: f64,
    },
    /// Particle weights are degenerate: all zero (every log-weight −∞), or some weight is NaN,
    /// negative or infinite.
    #[error("degenerate particle weights: {reason}")]
    WeightsDegenerate {
        /// What was wrong.
        reason: &'static str,
    },
}

impl From<FilterError> for CoreError {
    /// Maps a filter error onto the shared kinds, for trait methods that must return
    /// [`CoreError`].
    fn from(e: FilterError) -> Self {
        match e {
            FilterError::Core(c) => c,
            FilterError::NonFiniteMeasurement => CoreError::NonFinite {
                what: "measurement",
            },
            FilterError::InnovationNotPositiveDefinite => CoreError::NotPositiveDefinite {
                what: "innovation covariance",
            },
            FilterError::NonFiniteResult { what } => CoreError::NonFinite { what },
            FilterError::InvalidTimeStep { dt } => {
                CoreError::invalid("dt", format!("{dt} (must be finite and >= 0)"))
            }
            FilterError::WeightsDegenerate { reason } => {
                CoreError::numerical("particle weights", reason)
            }
        }
    }
}
