//! Smoothing a recorded SLAMOT run: the RBPF's forward estimate refined by
//! [`quarry_filter::smoother`] over the whole recording.
//!
//! The particle filter fixes each pose when it reaches it. On a real recording (UTIAS MRCLAM,
//! docs/slamot.md) its error is dominated by what a forward filter cannot undo: the map frame
//! set by biased odometry before the first landmark sighting, and the odometry-only heading
//! across stretches without landmarks. [`smooth_run`] takes the observations the tracker was
//! given, places a node at the start and at every observation epoch, starts from the tracker's
//! pose at each epoch and its final map, and solves for every pose, every landmark and
//! (optionally) the odometry's calibration at once, with the tracker's own noise values
//! ([`SlamotConfig::control_noise`], [`SlamotConfig::meas_noise`]). Targets are not part of the
//! smoothing (their detections barely move the pose: docs/slamot.md, diagnosis item 6); the
//! tracks stay the filter's.
//!
//! Both robot models are supported ([`RobotMotion::Unicycle`], [`RobotMotion::Bicycle`]: the
//! smoother integrates the same model as the particles), and landmarks carry their identity
//! (as SLAMOT's landmark detections always do).
//!
//! ```
//! use quarry_core::{LandmarkId, MultiTargetTracker, Pose2, Stamp};
//! use quarry_trackers::slamot::{SlamotConfig, SlamotObservation, SlamotTracker, smooth_run};
//! // a robot drives 0.5 m/s straight on, seeing a landmark at (3, 1) every 0.5 s
//! let cfg = SlamotConfig { particles: 20, ..SlamotConfig::mrclam() };
//! let mut tracker = SlamotTracker::new(cfg.clone(), Pose2::identity(), 1)?;
//! let mut obs = Vec::new();
//! let mut poses = Vec::new();
//! for k in 1..=40u64 {
//!     let x = 0.5 * 0.1 * k as f64;
//!     let observe = k % 5 == 0;
//!     let (dx, dy) = (3.0 - x, 1.0_f64);
//!     let o = SlamotObservation {
//!         dt: 0.1,
//!         odometry: (0.5, 0.0),
//!         observe,
//!         landmark_obs: if observe { vec![(LandmarkId(0), [dx.hypot(dy), dy.atan2(dx)])] } else { vec![] },
//!         target_obs: vec![],
//!     };
//!     tracker.step(Stamp::from_frame(k, 0.1), &o)?;
//!     if observe {
//!         poses.push(tracker.pose_estimate());
//!     }
//!     obs.push(o);
//! }
//! let s = smooth_run(&cfg, Pose2::identity(), &obs, Some(&poses), &tracker.map_estimate(), false)?;
//! assert_eq!(s.epoch_nodes, (1..=8).collect::<Vec<_>>());
//! let last = s.result.poses.last().unwrap();
//! assert!((last.x - 2.0).abs() < 0.05 && last.y.abs() < 0.05);
//! # Ok::<(), quarry_trackers::TrackerError>(())
//! ```

use quarry_core::{LandmarkId, Pose2};
use quarry_filter::smoother::{
    CalibrationPrior, LandmarkObservation, OdometryModel, OdometryStep, Smoothed, SmootherConfig,
    SmootherProblem, smooth,
};

use super::{RobotMotion, SlamotConfig, SlamotObservation};
use crate::TrackerError;

/// A smoothed run: the smoother's result and where its nodes sit in the observation sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothedRun {
    /// For every observation epoch (each observation with `observe == true`, in order), the
    /// index of its node in [`Smoothed::poses`]. Node 0 is the start pose; an epoch at the same
    /// time as the one before it shares its node.
    pub epoch_nodes: Vec<usize>,
    /// The smoothed poses (node 0 = start), landmarks, calibration and solver statistics.
    pub result: Smoothed,
}

/// The smoother settings for a SLAMOT configuration: its control and detection noise, a prior
/// on the start pose as tight as the tracker's anchor (1 mm, 1 mrad), the Huber loss (1.345),
/// and with `calibrate` the odometry calibration of [`CalibrationPrior::WEAK`].
pub fn smoother_config(cfg: &SlamotConfig, calibrate: bool) -> SmootherConfig {
    SmootherConfig {
        motion: match cfg.motion {
            RobotMotion::Unicycle => OdometryModel::Unicycle,
            RobotMotion::Bicycle { wheelbase } => OdometryModel::Bicycle { wheelbase },
        },
        control_sigma: cfg.control_noise,
        sigma_range: cfg.meas_noise[0],
        sigma_bearing: cfg.meas_noise[1],
        calibration: if calibrate {
            CalibrationPrior::WEAK
        } else {
            CalibrationPrior::NONE
        },
        ..SmootherConfig::default()
    }
}

/// Smooths a recorded run: the tracker's forward estimate refined by
/// [`quarry_filter::smoother::smooth`] over the whole recording, with the tracker's noise and
/// motion model (targets are not smoothed; their tracks stay the filter's).
///
/// `observations` are the tracker's inputs in order, `initial` the start pose the tracker was
/// anchored at. `guess_poses`, when given, holds the tracker's pose estimate at every observation
/// epoch (one per observation with `observe == true`, in order); without it the smoother starts
/// from dead reckoning. `guess_map` is the tracker's final map (landmarks it lacks start at their
/// first detection).
///
/// Errors: a guess of the wrong length, non-finite observations and everything [`smooth`]
/// refuses.
pub fn smooth_run(
    cfg: &SlamotConfig,
    initial: Pose2,
    observations: &[SlamotObservation],
    guess_poses: Option<&[Pose2]>,
    guess_map: &[(LandmarkId, [f64; 2])],
    calibrate: bool,
) -> Result<SmoothedRun, TrackerError> {
    let epochs = observations.iter().filter(|o| o.observe).count();
    if let Some(g) = guess_poses {
        quarry_core::ensure_len(g.len(), epochs, "guess poses (one per observation epoch)")?;
    }
    let mut steps = Vec::with_capacity(observations.len());
    let mut node_times = vec![0.0];
    let mut epoch_nodes = Vec::with_capacity(epochs);
    let mut init = guess_poses.map(|_| vec![initial]);
    let mut lm_obs = Vec::new();
    let mut t = 0.0;
    let mut epoch = 0usize;
    for o in observations {
        if !(o.dt.is_finite() && o.dt >= 0.0) {
            return Err(quarry_filter::FilterError::InvalidTimeStep { dt: o.dt }.into());
        }
        o.check_detections()?;
        if o.dt > 0.0 {
            t += o.dt;
            steps.push(OdometryStep {
                t_end: t,
                dt: o.dt,
                control: o.odometry,
            });
        }
        if !o.observe {
            continue;
        }
        // a node per epoch; an epoch at the same time as the previous node joins it
        let node = if t > *node_times.last().unwrap_or(&f64::NEG_INFINITY) {
            node_times.push(t);
            if let (Some(v), Some(g)) = (init.as_mut(), guess_poses) {
                v.push(g[epoch]);
            }
            node_times.len() - 1
        } else {
            node_times.len() - 1
        };
        epoch_nodes.push(node);
        epoch += 1;
        for (id, z) in &o.landmark_obs {
            lm_obs.push(LandmarkObservation {
                node,
                landmark: *id,
                range: z[0],
                bearing: z[1],
            });
        }
    }
    let problem = SmootherProblem {
        prior: initial,
        steps,
        node_times,
        observations: lm_obs,
        initial_poses: init,
        initial_landmarks: guess_map.to_vec(),
    };
    let result = smooth(&problem, &smoother_config(cfg, calibrate))?;
    Ok(SmoothedRun {
        epoch_nodes,
        result,
    })
}
