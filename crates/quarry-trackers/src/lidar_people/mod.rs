//! People tracking with distributed 2-D laser scanners (spec 003; Duan, Tian & Zhang 2014).
//!
//! The pipeline: per-scanner background subtraction (clients), fusion of the dynamic points of
//! all scanners into 50 ms frames (server), MeanShift clustering, ICP fit of an elliptical torso
//! contour, then a tracker. Four presets ([`Preset`]) switch the details over one code path: the paper's rules
//! (`literal`, `faithful`), a KF-GNN baseline (`kf-gnn`) and JIPDA with track existence
//! (`jipda`, [`JipdaPeopleTracker`]). For one scanner at leg height, `detector = legs`
//! ([`Detector`]) feeds the KF-GNN or JIPDA tracker with leg pairs from `quarry_cloud::legs`
//! instead of the torso-contour fits.
//!
//! The building blocks come from the other crates: `quarry_cloud` (background, MeanShift, ICP,
//! ellipse model, calibration), `quarry_assoc` (gate (8), Hungarian, M-of-N), `quarry_filter`
//! (the CV Kalman filter); the fusion over the wire format is `quarry_net::AssemblerFusion`, and
//! the runs on the room simulator are in `quarry_repro::lidar`.
//!
//! | file | holds |
//! |---|---|
//! | `config.rs` | [`LidarPeopleConfig`] (every parameter of §3, with its source), [`Preset`] |
//! | `tracker.rs` | the detector, the Table 1 and KF-GNN trackers, [`LidarPeopleTracker`] (the tracker of a preset) and the builders of its parts |
//! | `jipda.rs` | [`JipdaPeopleTracker`]: the detector feeding `cv_jpda`'s JIPDA tracker |
//! | `pipeline.rs` | the client and server halves: [`ClientPipeline`], the [`Fusion`] stage trait, [`ServerPipeline`] |
//! | `calibration.rs` | `calibration = icp`: [`calibrate_backgrounds`], [`PendingCalibration`] |
//! | `recorded.rs` | one recorded scanner: [`run_recorded`] |
//!
//! ```
//! use quarry_core::{MultiTargetTracker, Point2, Stamp, TimeUs};
//! use quarry_trackers::TrackerConfig;
//! use quarry_trackers::lidar_people::{DefaultLidarTracker, FusedPoints, LidarPeopleConfig, Preset};
//! let cfg = LidarPeopleConfig::preset(Preset::KfGnn);
//! let mut tracker = DefaultLidarTracker::from_config(&cfg)?;
//! // one person's torso contour (the near half of an ellipse), walking along x
//! for k in 0..6u64 {
//!     let (cx, cy) = (2.0 + 0.05 * k as f64, 3.0);
//!     let points = (0..40)
//!         .map(|i| {
//!             let a = std::f64::consts::PI * (1.0 + f64::from(i) / 40.0);
//!             Point2::new(cx + 0.22 * a.cos(), cy + 0.13 * a.sin())
//!         })
//!         .collect();
//!     let frame = FusedPoints { t: TimeUs(50_000 * k as i64), points, no_data: false };
//!     let reports = tracker.step(Stamp::from_frame(k, 0.05), &frame)?;
//!     assert!(reports.len() <= 1);
//! }
//! # Ok::<(), quarry_trackers::TrackerError>(())
//! ```

mod calibration;
mod config;
mod jipda;
mod pipeline;
mod recorded;
mod tracker;

pub use calibration::{
    CalibrationReport, FREE_SPACE_MARGIN_M, PendingCalibration, ScannerCalibration, ScannerInfo,
    calibrate_backgrounds, pose_error, reference_index,
};
pub use config::{
    Calibration, Detector, FusionTime, LidarPeopleConfig, MAX_ICP_IT, MAX_K_M, MAX_MIN_NUM_POINT,
    MAX_SECONDS, MAX_WINDOW_M, Preset,
};
pub use jipda::JipdaPeopleTracker;
pub use pipeline::{ClientPipeline, DynamicScan, Fusion, RowSource, ServerPipeline};
pub use recorded::{RecordedFrame, RecordedRun, run_recorded};
pub use tracker::{
    ContourDetector, ContourFit, DefaultLidarTracker, FusedPoints, KfGnnTracker,
    LidarPeopleTracker, LidarTrack, Table1Tracker, background_of, gate_of, icp_of, meanshift_of,
};
