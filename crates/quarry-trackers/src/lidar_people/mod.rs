//! People tracking with distributed 2-D laser scanners (spec 003; Duan, Tian & Zhang 2014).
//!
//! The pipeline: per-scanner background subtraction (clients), fusion of the dynamic points of
//! all scanners into 50 ms frames (server), MeanShift clustering, ICP fit of an elliptical torso
//! contour, and either the paper's Table 1 tracker with gate (8) or a CV-Kalman/GNN baseline.
//! Three presets ([`Preset`]) switch the details over one code path.
//!
//! The building blocks come from the other crates: `quarry_cloud` (background, MeanShift, ICP,
//! ellipse model, fusion), `quarry_assoc` (gate (8), Hungarian, M-of-N), `quarry_filter` (the CV
//! Kalman filter).

mod config;
mod metrics;
mod pipeline;
mod tracker;

pub use config::{LidarPeopleConfig, Preset};
pub use metrics::{
    EvalFrame, LocStats, Paper003Metrics, evaluate_paper003, loc_stats, match_within, paper_success,
};
pub use pipeline::{
    ClientPipeline, DynamicScan, Fusion, RoomRun, RowSource, ServerPipeline, run_room,
};
pub use tracker::{
    ContourDetector, ContourFit, FusedPoints, KfGnnTracker, LidarTrack, Table1Tracker, pca_angle,
};

use crate::TrackerError;
use quarry_assoc::PositionVelocityGate;
use quarry_core::{Clusterer, MultiTargetTracker, Point2, Registration2, Stamp, TrackReport};

/// The gate (8) with the σ and k of a configuration.
pub fn gate_of(cfg: &LidarPeopleConfig) -> PositionVelocityGate {
    PositionVelocityGate {
        sigma_pos: [cfg.sigma_pos; 2],
        sigma_vel: [cfg.sigma_vel; 2],
        k: cfg.gate_k,
        frame_period: cfg.frame_period_s,
    }
}

/// The tracker of a preset: Table 1 (`literal`, `faithful`) or KF-GNN (`kf-gnn`), over the same
/// detector.
#[derive(Debug, Clone)]
pub enum LidarPeopleTracker<C, R> {
    /// `literal` / `faithful`.
    Table1(Table1Tracker<C, R, PositionVelocityGate>),
    /// `kf-gnn`.
    KfGnn(KfGnnTracker<C, R>),
}

impl<C: Clusterer, R: Registration2> LidarPeopleTracker<C, R> {
    /// Assembles the tracker of `cfg.preset` from a clusterer, a registration and the contour
    /// model points (model frame).
    pub fn from_parts(
        cfg: &LidarPeopleConfig,
        clusterer: C,
        registration: R,
        model: Vec<Point2>,
    ) -> Result<Self, TrackerError> {
        cfg.validate()?;
        if model.len() < 3 {
            return Err(TrackerError::Config(
                "the contour model needs >= 3 points".into(),
            ));
        }
        let det = ContourDetector {
            clusterer,
            registration,
            model,
            axes: (cfg.a_m, cfg.b_m),
            r_m: cfg.r_m,
            min_num_point: cfg.min_num_point,
            d_m_matching: cfg.d_m_matching,
            two_starts: cfg.two_starts,
        };
        Ok(match cfg.preset {
            Preset::KfGnn => Self::KfGnn(KfGnnTracker::new(det, cfg)?),
            Preset::Literal | Preset::Faithful => {
                Self::Table1(Table1Tracker::new(det, gate_of(cfg), cfg))
            }
        })
    }

    /// The rows (`tracks.csv` columns) of the last processed frame.
    pub fn last_rows(&self) -> &[LidarTrack] {
        match self {
            Self::Table1(t) => t.last_rows(),
            Self::KfGnn(t) => t.last_rows(),
        }
    }
}

impl<C: Clusterer, R: Registration2> MultiTargetTracker for LidarPeopleTracker<C, R> {
    type Input = FusedPoints;
    type Error = TrackerError;
    fn step(
        &mut self,
        stamp: Stamp,
        input: &FusedPoints,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        match self {
            Self::Table1(t) => t.process(stamp, input),
            Self::KfGnn(t) => t.process(stamp, input),
        }
    }
}
