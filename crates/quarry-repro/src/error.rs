//! The crate's error type: an experiment fails in the simulator, the dataset reader, the tracker
//! or the scoring, and the variant keeps which (with its source).

use thiserror::Error;

/// Errors of quarry-repro.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ReproError {
    /// A shared error kind.
    #[error(transparent)]
    Core(#[from] quarry_core::CoreError),
    /// The tracker failed (or its configuration is unusable).
    #[error(transparent)]
    Tracker(#[from] quarry_trackers::TrackerError),
    /// The simulator rejected its scenario.
    #[error("scenario: {0}")]
    Sim(#[from] quarry_sim::SimError),
    /// A recording could not be read.
    #[error(transparent)]
    Data(#[from] quarry_data::DataError),
    /// Scoring failed.
    #[error(transparent)]
    Eval(#[from] quarry_eval::EvalError),
    /// The network layer (wire format, fusion, transport) failed.
    #[error(transparent)]
    Net(#[from] quarry_net::NetError),
    /// An experiment asked for something it cannot do (the message says what).
    #[error("{0}")]
    Invalid(String),
}

/// Shorthand result type.
pub type Result<T, E = ReproError> = std::result::Result<T, E>;
