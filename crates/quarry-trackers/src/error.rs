//! The crate's one error type: every tracker returns [`TrackerError`], and the errors of the
//! building blocks it calls become variants that keep their source (so `Error::source` walks
//! down to the quarry-filter, quarry-vision, ... error that started it).

use quarry_assoc::AssocError;
use quarry_cloud::CloudError;
use quarry_core::CoreError;
use quarry_filter::FilterError;
use quarry_vision::VisionError;
use thiserror::Error;

/// Errors of quarry-trackers.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TrackerError {
    /// A shared error kind (bad parameter, non-finite value, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A filter step failed (non-finite measurement, S not positive definite, ...).
    #[error(transparent)]
    Filter(#[from] FilterError),
    /// An association step failed.
    #[error(transparent)]
    Assoc(#[from] AssocError),
    /// A point-cloud step failed (ICP, MeanShift, background model, ...).
    #[error(transparent)]
    Cloud(#[from] CloudError),
    /// An image / descriptor step failed.
    #[error(transparent)]
    Vision(#[from] VisionError),
    /// A tracker configuration that cannot be used (the message names the key and the value).
    #[error("invalid {tracker} configuration: {reason}")]
    Config {
        /// Which tracker's configuration (`slamot`, `lidar_people`, ...).
        tracker: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A TOML configuration that does not parse or does not fit the tracker's configuration
    /// (unknown key, wrong type, ...). The line and the key are the user's, in the user's file
    /// (not in the preset the file is laid over), where they could be found.
    #[error(
        "{tracker} configuration {}{}{}: {}",
        file.as_deref().unwrap_or("TOML"),
        line.map(|l| format!(", line {l}")).unwrap_or_default(),
        key.as_deref().map(|k| format!(", key `{k}`")).unwrap_or_default(),
        toml_message(error)
    )]
    Toml {
        /// Which tracker's configuration.
        tracker: &'static str,
        /// The file it was read from, when it was.
        file: Option<String>,
        /// The 1-based line of the offending key or value in the user's text, when known.
        line: Option<usize>,
        /// The dotted path of the offending key (`model.n`), when known.
        key: Option<String>,
        /// The TOML error (boxed: it is large and rare).
        error: Box<toml::de::Error>,
    },
    /// A preset name that the tracker does not have.
    #[error("unknown {tracker} preset {name:?} (expected one of: {expected})")]
    UnknownPreset {
        /// Which tracker.
        tracker: &'static str,
        /// The name given.
        name: String,
        /// The preset names, comma separated.
        expected: String,
    },
    /// Input that does not fit the tracker's state (e.g. `step` before `init`, a frame of
    /// another size than the one it was initialised on).
    #[error("{0}")]
    State(String),
    /// Every particle weight is zero, −∞ or NaN after the update of this epoch (slamot).
    #[error("particle weights degenerate at control step {step}")]
    WeightsDegenerate {
        /// Control step index.
        step: u64,
    },
    /// Extrinsic calibration failed for one scanner (spec 003 §2.3): e.g. quarry-cloud's
    /// `CalibrationInsufficient` (overlap or inlier RMS out of bounds), or no usable background.
    #[error("calibration of scanner {scanner} failed: {reason}")]
    Calibration {
        /// The scanner's name and sensor id.
        scanner: String,
        /// Why.
        reason: String,
        /// The quarry-cloud error, when there is one (its text is in `reason`).
        #[source]
        cloud: Option<CloudError>,
    },
}

impl TrackerError {
    /// A [`TrackerError::Config`] for `tracker` (the configuration's
    /// [`TrackerConfig::NAME`](crate::TrackerConfig::NAME)).
    pub fn config(tracker: &'static str, reason: impl Into<String>) -> Self {
        Self::Config {
            tracker,
            reason: reason.into(),
        }
    }
}

/// The TOML error's message on one line: a syntax error keeps its own caret drawing of the
/// line; a deserialisation error is just its message (the key and line are said separately).
fn toml_message(e: &toml::de::Error) -> String {
    if e.span().is_some() {
        e.to_string().trim_end().to_owned()
    } else {
        e.message().to_owned()
    }
}
