//! EKF-SLAMOT: the paper's baseline (its reference \[8\]) — one joint extended Kalman filter over
//! the robot pose, every landmark and every target, to compare against the Rao-Blackwellized
//! [`SlamotTracker`](crate::slamot::SlamotTracker).
//!
//! The state is `x = [x_R (3) | m_1 (2) … m_M (2) | s_1 (4) … s_n (4)]`, blocks appended in the
//! order they are first seen, with one dense covariance `P` of dimension `D = 3 + 2M + 4n`, held
//! in a [`faer::Mat`] (the "large dynamic covariance"). Every cost is O(D) or O(D²):
//!
//! - control step: robot prediction through the motion model's Jacobians; only the robot rows
//!   and columns of `P` change (`P_RR ← F P_RR Fᵀ + G Q_u Gᵀ`, `P_R· ← F P_R·`), O(D);
//! - observation epoch, landmarks: a new landmark is appended with its cross-covariance
//!   `G_x P_R·` (inverse range-bearing model); a known one is a sequential EKF update with the
//!   sparse `H = [H_x | … H_p …]`, `K = P Hᵀ S⁻¹`, `P ← P − K S Kᵀ` (rank 2, O(D²));
//! - targets: CV prediction of every target block (DWNA σ_a, as the RBPF), then the same
//!   association as the RBPF (quarry-assoc's `Jpda` / `PaperLikelihood` / `Jipda` on the gated
//!   likelihood matrix built from the joint predictive `S_l = H_l P H_lᵀ + R`, which includes the
//!   robot–target correlation), then the PDA combined-innovation update of each target on the
//!   joint state: `x ← x + K ν̄`, `P ← P − K ((1 − β₀) S − P̃) Kᵀ`, `P̃ = Σ_j β_j ν_j ν_jᵀ − ν̄ ν̄ᵀ`.
//!   Targets are updated one after the other with the β of the joint association (computed once
//!   from the prediction) and their innovations re-linearised at the current state — the
//!   standard sequential JPDA-EKF; the order is the slot order.
//! - target initiation is the RBPF's ([`TargetInit`](crate::slamot::TargetInit)): first epoch
//!   with n detections, or two-point.
//!
//!
//! The filter takes the RBPF's configuration ([`SlamotConfig`](crate::slamot::SlamotConfig),
//! its presets and TOML included) and its input ([`SlamotObservation`](crate::slamot::SlamotObservation)).
//! Files: `tracker.rs` ([`EkfSlamot`]). The runs on the simulated scenarios are
//! `quarry_repro::slamot::run_simulated_ekf`.
//!
//! A robot standing still at the origin sees one landmark and three targets moving along x:
//!
//! ```
//! use quarry_core::{LandmarkId, MultiTargetTracker, Pose2, Stamp};
//! use quarry_trackers::ekf_slamot::EkfSlamot;
//! use quarry_trackers::slamot::{SlamotConfig, SlamotObservation};
//! let mut ekf = EkfSlamot::new(SlamotConfig::default(), Pose2::identity())?;
//! let rb = |px: f64, py: f64| [px.hypot(py), py.atan2(px)];
//! let mut reports = Vec::new();
//! for k in 0..10u64 {
//!     let x = 0.2 * k as f64;
//!     let obs = SlamotObservation {
//!         dt: 0.2,
//!         odometry: (0.0, 0.0),
//!         observe: true,
//!         landmark_obs: vec![(LandmarkId(7), rb(10.0, 10.0))],
//!         target_obs: vec![rb(5.0 + x, 0.0), rb(x, 8.0), rb(x - 6.0, -4.0)],
//!     };
//!     reports = ekf.step(Stamp::from_frame(k, 0.2), &obs)?;
//! }
//! assert_eq!(reports.len(), 3);
//! assert_eq!(ekf.dim(), 3 + 2 * ekf.map_estimate().len() + 4 * 3);
//! let xy = reports[0].xy().unwrap();
//! assert!((xy[0] - 6.8).abs() < 0.5 && xy[1].abs() < 0.5);
//! let p = ekf.pose_estimate();
//! assert!(p.x.hypot(p.y) < 0.5);
//! # Ok::<(), quarry_trackers::TrackerError>(())
//! ```

mod tracker;

pub use tracker::EkfSlamot;
