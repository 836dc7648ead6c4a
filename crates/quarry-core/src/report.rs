//! The record every tracker reports, so that quarry-eval scores any of them.

use crate::{BBox, Stamp, TrackId};
use nalgebra::{DMatrix, DVector};

/// How the numbers of a [`StateEstimate`] are laid out (position always first).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum StateLayout {
    /// `[x, y]`.
    Xy,
    /// `[x, y, vx, vy]`.
    XyVxVy,
    /// `[x, y, heading]`.
    XyHeading,
    /// `[x, y, vx, vy, heading]`.
    XyVxVyHeading,
    /// `[x, y, z, vx, vy]` (spec 001's MEKF state, robot frame).
    XyzVxVy,
}

impl StateLayout {
    /// Number of state components.
    pub fn dim(self) -> usize {
        match self {
            StateLayout::Xy => 2,
            StateLayout::XyHeading => 3,
            StateLayout::XyVxVy => 4,
            StateLayout::XyVxVyHeading | StateLayout::XyzVxVy => 5,
        }
    }
}

/// A state mean (and optionally its covariance) in the tracker's output frame.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct StateEstimate {
    /// Component order.
    pub layout: StateLayout,
    /// The mean, `layout.dim()` numbers.
    pub mean: DVector<f64>,
    /// The covariance, when the tracker has one.
    pub cov: Option<DMatrix<f64>>,
}

impl StateEstimate {
    /// The position `(x, y)` (the first two components of every layout).
    pub fn xy(&self) -> Option<[f64; 2]> {
        (self.mean.len() >= 2).then(|| [self.mean[0], self.mean[1]])
    }
}

/// A track's life-cycle status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TrackStatus {
    /// Born, not yet confirmed.
    Tentative,
    /// Confirmed and updated by a measurement this step.
    Confirmed,
    /// Confirmed, partly or wholly hidden; still updated where visible.
    Occluded,
    /// Prediction only (no measurement used this step).
    Coasting,
}

/// A set of event flags on a track report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TrackFlags(pub u32);

impl TrackFlags {
    /// No flag.
    pub const NONE: TrackFlags = TrackFlags(0);
    /// The track was created this step.
    pub const BORN: TrackFlags = TrackFlags(1);
    /// The track's estimate was replaced because its gate failed (spec 003, Table 1).
    pub const GATE_REPLACED: TrackFlags = TrackFlags(1 << 1);
    /// The track was confirmed this step.
    pub const CONFIRMED_NOW: TrackFlags = TrackFlags(1 << 2);
    /// The track ends with this report.
    pub const DYING: TrackFlags = TrackFlags(1 << 3);
    /// The track was recovered after being lost or fully occluded.
    pub const RECOVERED: TrackFlags = TrackFlags(1 << 4);
    /// The appearance template was updated this step.
    pub const TEMPLATE_UPDATED: TrackFlags = TrackFlags(1 << 5);

    /// True when every flag of `other` is set.
    pub fn contains(self, other: TrackFlags) -> bool {
        self.0 & other.0 == other.0
    }
    /// Sets the flags of `other`.
    pub fn insert(&mut self, other: TrackFlags) {
        self.0 |= other.0;
    }
}

impl std::ops::BitOr for TrackFlags {
    type Output = TrackFlags;
    fn bitor(self, rhs: TrackFlags) -> TrackFlags {
        TrackFlags(self.0 | rhs.0)
    }
}

/// What a tracker reports for one track at one step.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TrackReport {
    /// The step this report belongs to.
    pub stamp: Stamp,
    /// The track identity.
    pub id: TrackId,
    /// Life-cycle status.
    pub status: TrackStatus,
    /// Mean (and covariance) in the tracker's output frame.
    pub state: Option<StateEstimate>,
    /// Image box (image trackers).
    pub bbox: Option<BBox>,
    /// Existence probability (JIPDA).
    pub existence: Option<f64>,
    /// Tracker-specific quality (001: S, 003: ICP RMS, 004: 1.0).
    pub score: Option<f64>,
    /// Events of this step.
    pub flags: TrackFlags,
}

impl TrackReport {
    /// A report with only the required fields set.
    pub fn new(stamp: Stamp, id: TrackId, status: TrackStatus) -> Self {
        Self {
            stamp,
            id,
            status,
            state: None,
            bbox: None,
            existence: None,
            score: None,
            flags: TrackFlags::NONE,
        }
    }
    /// The position `(x, y)` of the state estimate, if any.
    pub fn xy(&self) -> Option<[f64; 2]> {
        self.state.as_ref().and_then(StateEstimate::xy)
    }
}
