//! Paper 000 (PFJPDA_SLAMOT): the experiments of spec §4 on the simulated scenarios S0/S1 of
//! `quarry_sim::slamot` and on the UTIAS MRCLAM recordings of `quarry_data::mrclam`, with the
//! scores of §4.2 (the tracker itself is `quarry_trackers::slamot`, the joint-EKF baseline
//! `quarry_trackers::ekf_slamot`).
//!
//! - `sim.rs`: [`run_simulated`] / [`run_frames`] (the RBPF), [`run_simulated_ekf`] (the
//!   baseline), both scored by [`score_frames`] into a [`SimRunResult`]; [`mean_var`],
//!   [`assign_slots`];
//! - `mrclam.rs`: [`run_mrclam`] into a [`MrclamResult`], [`mrclam_config`], and
//!   [`smooth_mrclam`] (the forward run refined by the batch smoother) into an
//!   [`MrclamSmoothed`];
//! - `score.rs`: the scores shared with the Python peers ([`score_trajectory`] (ATE with and
//!   without rigid SE(2) alignment), [`score_map`], [`score_targets`] (OSPA / GOSPA));
//! - here: the frame → [`SlamotObservation`] conversions ([`observation`],
//!   [`mrclam_observation`]) and the filter seed of a Monte-Carlo run ([`filter_seed`]).
//!
//! The tracker driven by hand over a simulated scenario:
//!
//! ```
//! use quarry_core::{MultiTargetTracker, Stamp};
//! use quarry_repro::slamot::observation;
//! use quarry_sim::slamot::{simulate, SlamotScenarioConfig};
//! use quarry_trackers::slamot::{SlamotConfig, SlamotTracker};
//! let mut scen = SlamotScenarioConfig::s0();
//! scen.duration = 4.0;
//! let frames = simulate(&scen, 1)?;
//! let cfg = SlamotConfig { particles: 10, ..SlamotConfig::default() };
//! let mut tracker = SlamotTracker::new(cfg, quarry_core::Pose2::new(4.0, 54.0, 0.0), 42)?;
//! let mut reports = Vec::new();
//! for f in &frames {
//!     reports = tracker.step(Stamp::from_frame(f.k, scen.dt_control), &observation(f))?;
//! }
//! assert_eq!(reports.len(), 3);
//! let p = tracker.pose_estimate();
//! assert!((p.x - frames.last().unwrap().truth.robot.x).abs() < 1.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The same with the EKF-SLAMOT baseline:
//!
//! ```
//! use quarry_core::{MultiTargetTracker, Stamp};
//! use quarry_repro::slamot::observation;
//! use quarry_sim::slamot::{simulate, SlamotScenarioConfig};
//! use quarry_trackers::ekf_slamot::EkfSlamot;
//! use quarry_trackers::slamot::SlamotConfig;
//! let mut scen = SlamotScenarioConfig::s0();
//! scen.duration = 4.0;
//! let frames = simulate(&scen, 1)?;
//! let mut ekf = EkfSlamot::new(SlamotConfig::default(), quarry_core::Pose2::new(4.0, 54.0, 0.0))?;
//! let mut reports = Vec::new();
//! for f in &frames {
//!     reports = ekf.step(Stamp::from_frame(f.k, scen.dt_control), &observation(f))?;
//! }
//! assert_eq!(reports.len(), 3);
//! assert_eq!(ekf.dim(), 3 + 2 * ekf.map_estimate().len() + 4 * 3);
//! let p = ekf.pose_estimate();
//! assert!((p.x - frames.last().unwrap().truth.robot.x).abs() < 1.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod mrclam;
mod score;
mod sim;

use quarry_core::rng::stream;
use quarry_data::mrclam::MrclamFrame;
use quarry_sim::slamot::SlamotFrame;
use quarry_trackers::slamot::SlamotObservation;

pub use mrclam::{
    MrclamResult, MrclamSmoothed, TrackRow, mrclam_config, run_mrclam, smooth_mrclam,
};
pub use score::{
    MapScore, Se2, TargetEpoch, TrajectoryScore, align_se2, score_map, score_targets,
    score_trajectory,
};
pub use sim::{
    SimRunResult, assign_slots, mean_var, run_frames, run_simulated, run_simulated_ekf,
    score_frames,
};

/// What the tracker sees of a simulated frame: the frame without its truth.
pub fn observation(f: &SlamotFrame) -> SlamotObservation {
    SlamotObservation {
        dt: f.dt,
        odometry: f.odometry,
        observe: f.observe,
        landmark_obs: f.landmark_obs.clone(),
        target_obs: f.target_obs.clone(),
    }
}

/// What the tracker sees of an MRCLAM frame: odometry and the barcoded landmark detections,
/// the other robots' detections without their barcodes (the truth stays behind).
pub fn mrclam_observation(f: &MrclamFrame) -> SlamotObservation {
    SlamotObservation {
        dt: f.dt,
        odometry: f.odometry,
        observe: f.observe,
        landmark_obs: f.landmark_obs.clone(),
        target_obs: f.target_obs.clone(),
    }
}

/// The filter seed of run r at N particles: hash(r, N) (spec §3.2; common truth across N).
pub fn filter_seed(run: u64, particles: usize) -> u64 {
    use rand::RngCore;
    stream(run, &[particles as u64, 0x5EED]).next_u64()
}
