//! PFJPDA_SLAMOT (spec 000): a Rao-Blackwellized particle filter that does SLAM and tracks
//! several moving targets in one filter.
//!
//! Every particle carries a robot pose (a sample), a landmark map of 2-D Gaussians (FastSLAM 1.0,
//! in a [`LandmarkStore`](quarry_core::LandmarkStore), by default quarry-filter's persistent tree
//! so that resampling copies a particle in O(1)) and one 4-D constant-velocity Gaussian per
//! target slot. At an observation epoch each particle updates its landmarks (known
//! correspondences), predicts its targets, builds the gated likelihood matrix of the target
//! detections and associates them with quarry-assoc ([`AssociationMode::Jpda`] default,
//! [`AssociationMode::Paper`] = the paper's eqs. (5), (11), (12), [`AssociationMode::Jipda`] =
//! Musicki-Evans with existence, births and deaths), updates every target with the PDA combined
//! innovation, and multiplies its weight by the landmark and target factors. Weights are
//! normalised, estimates read out, and particles resampled (stratified) when N_eff < 0.75 N.
//! Per-particle work runs on rayon (feature `rayon`) with per-particle random streams
//! `stream(seed, [step, particle])`, so results do not depend on the thread count.
//!
//! Files: `config.rs` ([`SlamotConfig`], its enums and the [`Preset`]s `paper` (= `Default`),
//! `s1`, `mrclam`), `observation.rs` (the input, [`SlamotObservation`]), `tracker.rs`
//! ([`SlamotTracker`], the particle set), `particle.rs` (one particle's epoch), `init.rs`
//! (two-point target initiation, shared with [`ekf_slamot`](crate::ekf_slamot)), `smooth.rs`
//! ([`smooth_run`]: the forward estimate of a recorded run refined by a batch smoother). The runs on the
//! simulated scenarios S0/S1 and on MRCLAM, with the paper's scores, are in
//! `quarry_repro::slamot`.
//!
//! A robot standing still at the origin sees one landmark and three targets, which move 0.2 m
//! along x between epochs:
//!
//! ```
//! use quarry_core::{LandmarkId, MultiTargetTracker, Pose2, Stamp};
//! use quarry_trackers::slamot::{SlamotConfig, SlamotObservation, SlamotTracker};
//! use quarry_trackers::TrackerConfig;
//! let cfg = SlamotConfig { particles: 10, ..SlamotConfig::default() };
//! cfg.validate()?;
//! let mut tracker = SlamotTracker::new(cfg, Pose2::identity(), 42)?;
//! let mut reports = Vec::new();
//! for k in 0..10u64 {
//!     let x = 0.2 * k as f64;
//!     // targets at (5 + x, 0), (x, 8), (x - 6, -4): [range, bearing] from the origin
//!     let rb = |px: f64, py: f64| [px.hypot(py), py.atan2(px)];
//!     let obs = SlamotObservation {
//!         dt: 0.2,
//!         odometry: (0.0, 0.0),
//!         observe: true,
//!         landmark_obs: vec![(LandmarkId(7), rb(10.0, 10.0))],
//!         target_obs: vec![rb(5.0 + x, 0.0), rb(x, 8.0), rb(x - 6.0, -4.0)],
//!     };
//!     reports = tracker.step(Stamp::from_frame(k, 0.2), &obs)?;
//! }
//! assert_eq!(reports.len(), 3);
//! let xy = reports[0].xy().unwrap();
//! assert!((xy[0] - 6.8).abs() < 0.5 && xy[1].abs() < 0.5);
//! let p = tracker.pose_estimate();
//! assert!(p.x.hypot(p.y) < 0.5);
//! assert_eq!(tracker.map_estimate().len(), 1);
//! # Ok::<(), quarry_trackers::TrackerError>(())
//! ```
//!
//! A configuration from TOML, laid over a preset:
//!
//! ```
//! use quarry_trackers::slamot::{AssociationMode, Preset, SlamotConfig};
//! use quarry_trackers::TrackerConfig;
//! let cfg = SlamotConfig::from_toml("particles = 20\nassociation = \"paper\"", Some(Preset::S1))?;
//! assert_eq!(cfg, SlamotConfig { particles: 20, association: AssociationMode::Paper, ..SlamotConfig::s1() });
//! assert!(SlamotConfig::from_toml("particle = 20", None).is_err()); // a typo is an error
//! # Ok::<(), quarry_trackers::TrackerError>(())
//! ```

mod config;
mod init;
mod observation;
mod particle;
mod smooth;
mod tracker;

pub use config::{
    AssociationMode, MAX_PARTICLES, MapStoreKind, Preset, Proposal, Readout, RobotMotion,
    SlamotConfig, TargetInit, TargetMotion, TargetWeight,
};
pub(crate) use init::{MapPoints, two_point_gaussian, two_point_pairs};
pub use observation::{MAX_CONTROL, MAX_RANGE_M, MAX_STEP_S, MIN_RANGE_M, SlamotObservation};
pub use particle::{SlamotParticle, TargetSlot};
pub use smooth::{SmoothedRun, smooth_run, smoother_config};
pub use tracker::{DefaultStore, EpochStats, FlatStore, SlamotTracker};
