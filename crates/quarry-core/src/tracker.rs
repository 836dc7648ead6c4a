//! The tracker traits.

use crate::{BBox, Stamp, TrackReport};

/// A multi-target tracker: one call per frame, one report per live track.
pub trait MultiTargetTracker {
    /// The per-frame input (detections, a scan set, an image, ...).
    type Input;
    /// The tracker's error type.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Processes one frame and reports every live track.
    fn step(&mut self, stamp: Stamp, input: &Self::Input) -> Result<Vec<TrackReport>, Self::Error>;
}

/// A single-target tracker initialised from a box.
pub trait SingleTargetTracker {
    /// The per-frame input.
    type Input;
    /// The per-frame output; converts to a report (`None` when the target is lost).
    type Output: Into<Option<TrackReport>>;
    /// The tracker's error type.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Initialises the target from `bbox` in the first frame.
    fn init(&mut self, stamp: Stamp, input: &Self::Input, bbox: BBox) -> Result<(), Self::Error>;
    /// Processes one frame.
    fn step(&mut self, stamp: Stamp, input: &Self::Input) -> Result<Self::Output, Self::Error>;
}
