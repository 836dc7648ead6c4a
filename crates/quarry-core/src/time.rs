//! Time stamps and identifiers.

/// A time on the run's timeline, in microseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TimeUs(pub i64);

impl TimeUs {
    /// From seconds (rounded to the nearest microsecond).
    pub fn from_secs_f64(s: f64) -> Self {
        Self((s * 1e6).round() as i64)
    }
    /// In seconds.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-6
    }
    /// `self - earlier` in seconds (the `dt` handed to models).
    pub fn secs_since(self, earlier: TimeUs) -> f64 {
        (self.0 - earlier.0) as f64 * 1e-6
    }
}

/// A 0-based frame index (MOTChallenge files add 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct FrameIndex(pub u64);

/// When an input was taken: its frame index and its time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Stamp {
    /// 0-based frame index.
    pub frame: FrameIndex,
    /// Time on the run's timeline.
    pub t: TimeUs,
}

impl Stamp {
    /// A stamp for frame `k` of a sequence sampled every `dt` seconds, starting at t = 0.
    pub fn from_frame(k: u64, dt: f64) -> Self {
        Self {
            frame: FrameIndex(k),
            t: TimeUs::from_secs_f64(k as f64 * dt),
        }
    }
}

/// A track identity, never reused within a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TrackId(pub u32);

/// A landmark identity (an index into a [`crate::LandmarkStore`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LandmarkId(pub u32);

/// A sensor identity (one laser scanner, one camera).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SensorId(pub u16);

impl std::fmt::Display for TrackId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}
