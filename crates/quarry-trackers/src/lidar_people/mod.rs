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

mod calibration;
mod config;
mod metrics;
mod pipeline;
mod recorded;
mod tracker;

pub use calibration::{
    CalibrationReport, ScannerCalibration, calibrate_backgrounds, calibrate_scenario, pose_error,
    rough_poses,
};
pub use config::{Calibration, FusionTime, LidarPeopleConfig, Preset};
pub use metrics::{
    EvalFrame, LocStats, Paper003Metrics, evaluate_paper003, loc_stats, match_within, paper_success,
};
pub use pipeline::{
    AssemblerFusion, ClientPipeline, DynamicScan, Fusion, RoomRun, RowSource, ServerPipeline,
    encode_dynamic, run_room, run_room_default,
};
pub use recorded::{
    LabelledError, LabelledPerson, RecordedFrame, RecordedRun, parse_legs_csv, run_recorded,
    score_labelled,
};
pub use tracker::{
    ContourDetector, ContourFit, FusedPoints, KfGnnTracker, LidarTrack, Table1Tracker,
};

use crate::TrackerConfig as _;
use crate::TrackerError;
use quarry_assoc::PositionVelocityGate;
use quarry_cloud::background::{ChiSquareBackground, ChiSquareConfig, LongTermConfig, SigmaMode};
use quarry_cloud::cluster::MeanShift;
use quarry_cloud::contour::EllipseModel;
use quarry_cloud::icp::{Correspondence, Icp2d, Trim};
use quarry_core::{
    Clusterer, CoreError, MultiTargetTracker, Registration2, ScanGeometry, Stamp, TrackReport,
};

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
    /// Assembles the tracker of `cfg.preset` from a clusterer and a registration; the contour
    /// model is the ellipse of `cfg` (a_m, b_m, K_m).
    pub fn from_parts(
        cfg: &LidarPeopleConfig,
        clusterer: C,
        registration: R,
    ) -> Result<Self, TrackerError> {
        cfg.validate()?;
        let ellipse = EllipseModel {
            a: cfg.a_m,
            b: cfg.b_m,
            k: cfg.k_m,
        };
        let model = ellipse.points().map_err(CoreError::from)?;
        let det = ContourDetector {
            clusterer,
            registration,
            model,
            ellipse,
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

/// The tracker with quarry-cloud's MeanShift and contour ICP.
pub type DefaultLidarTracker = LidarPeopleTracker<MeanShift, Icp2d>;

/// MeanShift with the §2.5 parameters of `cfg`.
pub fn meanshift_of(cfg: &LidarPeopleConfig) -> MeanShift {
    MeanShift {
        min_cluster_size: cfg.n_min_cluster,
        ..MeanShift::with_bandwidth(cfg.bandwidth)
    }
}

/// The contour ICP with the §2.6 switches of `cfg`.
pub fn icp_of(cfg: &LidarPeopleConfig) -> Icp2d {
    Icp2d {
        direction: if cfg.icp_data_to_model {
            Correspondence::DataToModel
        } else {
            Correspondence::ModelToData
        },
        trim: cfg.icp_trim.then(Trim::default),
        rms_stop: cfg.icp_e,
        delta_stop: cfg.icp_eps_delta,
        max_iter: cfg.icp_it_max,
        require_full_model: !cfg.icp_data_to_model,
        ..Icp2d::default()
    }
}

/// The chi-square background of §2.2 for a scanner of `geometry`, with the switches of `cfg`.
pub fn background_of(
    cfg: &LidarPeopleConfig,
    geometry: &ScanGeometry,
) -> Result<ChiSquareBackground, TrackerError> {
    let per_scan = |s: f64| (s / geometry.scan_period.max(1e-6)).round().max(1.0);
    let bc = ChiSquareConfig {
        window: cfg.window_m,
        p_threshold: cfg.p_th,
        kappa: cfg.kappa,
        sigma: SigmaMode::Datasheet,
        region_constraint: true,
        region_radius: cfg.delta_region,
        long_term: cfg.revealed_background.then(|| LongTermConfig {
            warm_scans: per_scan(cfg.t_warm_s) as usize,
            min_valid_fraction: 0.5,
            alpha: cfg.alpha_b,
            relearn_scans: per_scan(cfg.t_relearn_s) as u32,
            gated_update: cfg.bg_gated_update,
        }),
    };
    Ok(ChiSquareBackground::new(geometry, bc).map_err(CoreError::from)?)
}

impl DefaultLidarTracker {
    /// The tracker of `cfg` with quarry-cloud's MeanShift and ICP.
    pub fn from_config(cfg: &LidarPeopleConfig) -> Result<Self, TrackerError> {
        Self::from_parts(cfg, meanshift_of(cfg), icp_of(cfg))
    }
}
