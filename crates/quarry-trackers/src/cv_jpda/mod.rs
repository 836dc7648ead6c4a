//! Stand-alone CV-Kalman + JPDA/JIPDA multi-target tracker (quarry-assoc's reference tracker).
//!
//! A small stand-alone multi-target tracker: constant-velocity Kalman filter per track, χ²
//! gating, JPDA or JIPDA association (quarry-assoc) and the PDA combined-innovation update
//! (spec 000 §2.9), with track birth, confirmation and deletion.
//!
//! - **Known targets** ([`JpdaTracker::with_tracks`]): fixed track set, no birth or deletion —
//!   the "known n" workload of the Stone Soup peer benchmark.
//! - **Unknown count** ([`JpdaTracker::new`]): every detection left unexplained
//!   (`Σ_i β_ij < 0.5`) starts a tentative track at the detection with zero velocity and
//!   variance `birth_vel_sigma²`. With [`AssocMode::Jipda`] each track carries an existence
//!   probability ψ (birth ψ₀, survival p_S per scan) and is confirmed/deleted by
//!   [`ExistenceThresholds`](quarry_assoc::lifecycle::ExistenceThresholds); with
//!   [`AssocMode::Jpda`] by M-of-N on "detected" = β_i0 < 0.5.
//!
//! The state is `[x, y, vx, vy]`, measurements are positions.
//!
//! Files: `config.rs` ([`JpdaTrackerConfig`], [`AssocMode`] and the [`Preset`]s `jipda`
//! (= `Default`, the shared `jpda_n*` bench scenarios) and `jpda`), `tracker.rs`
//! ([`JpdaTracker`], [`Track`]).
//!
//! ```
//! use nalgebra::Vector4;
//! use quarry_core::{MultiTargetTracker, Stamp};
//! use quarry_trackers::cv_jpda::{JpdaTracker, JpdaTrackerConfig};
//! let cfg = JpdaTrackerConfig::default();
//! let mut t = JpdaTracker::new(cfg)?;
//! let mut out = Vec::new();
//! for k in 0..8u64 {
//!     let x = k as f64;
//!     out = t.step(Stamp::from_frame(k, 1.0), &vec![[x, 0.0], [20.0 + 0.5 * x, 10.0]])?;
//! }
//! assert_eq!(out.len(), 2);          // both targets confirmed
//! let p = out.iter().find(|r| r.xy().unwrap()[1] < 5.0).unwrap().xy().unwrap();
//! assert!((p[0] - 7.0).abs() < 0.5);
//! # let _ = Vector4::<f64>::zeros();
//! # Ok::<(), quarry_trackers::TrackerError>(())
//! ```

mod config;
mod tracker;

pub use config::{AssocMode, JpdaTrackerConfig, Preset};
pub use tracker::{JpdaTracker, Track};
