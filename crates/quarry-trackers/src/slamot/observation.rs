//! [`SlamotObservation`]: what the tracker (and the EKF-SLAMOT baseline) sees at one control
//! step. The simulator's frames and the MRCLAM reader's frames become observations in
//! quarry-repro (`quarry_repro::slamot::observation`, `mrclam_observation`).

use quarry_core::{CoreError, LandmarkId};
use serde::{Deserialize, Serialize};

/// What the tracker sees at one control step: a frame without its truth.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SlamotObservation {
    /// Control step length \[s\].
    pub dt: f64,
    /// Odometry control ((V, G) for the bicycle, (v, ω) for the unicycle).
    pub odometry: (f64, f64),
    /// Observation epoch (landmark/target detections processed).
    pub observe: bool,
    /// Landmark detections (external id, [range, bearing]).
    pub landmark_obs: Vec<(LandmarkId, [f64; 2])>,
    /// Target detections [range, bearing], no identity.
    pub target_obs: Vec<[f64; 2]>,
}

/// The longest control step a tracker accepts \[s\] (one hour: a longer step is a broken
/// clock, and its motion noise would swamp everything).
pub const MAX_STEP_S: f64 = 3600.0;
/// The largest odometry control magnitude accepted (m/s, rad/s or rad: far above any ground
/// robot; larger values overflow the pose long before they mean anything).
pub const MAX_CONTROL: f64 = 1.0e4;
/// The largest detection range accepted \[m\].
pub const MAX_RANGE_M: f64 = 1.0e6;
/// The smallest detection range accepted \[m\] (1 mm: below it the inverse range-bearing model
/// gives a covariance too thin to be positive definite in floating point).
pub const MIN_RANGE_M: f64 = 1.0e-3;

impl SlamotObservation {
    /// Checks the step length (finite, in [0, [`MAX_STEP_S`]]) and the odometry (finite, each
    /// component at most [`MAX_CONTROL`] in magnitude).
    pub fn check_controls(&self) -> Result<(), CoreError> {
        let (v, g) = self.odometry;
        if !(v.is_finite() && g.is_finite()) {
            return Err(CoreError::NonFinite { what: "odometry" });
        }
        if v.abs() > MAX_CONTROL || g.abs() > MAX_CONTROL {
            return Err(CoreError::invalid(
                "odometry",
                format!("({v}, {g}) (each component must be at most {MAX_CONTROL} in magnitude)"),
            ));
        }
        if !(self.dt.is_finite() && (0.0..=MAX_STEP_S).contains(&self.dt)) {
            return Err(CoreError::invalid(
                "dt",
                format!("{} (must be finite and in [0, {MAX_STEP_S}] s)", self.dt),
            ));
        }
        Ok(())
    }

    /// Checks that every landmark and target detection is finite with a range in
    /// [[`MIN_RANGE_M`], [`MAX_RANGE_M`]] (what both
    /// the RBPF and the EKF-SLAMOT baseline require before an observation epoch; a zero range
    /// is no detection, and readers skip it: `quarry_data::mrclam` counts them).
    pub fn check_detections(&self) -> Result<(), CoreError> {
        let bad_range = |r: f64| r.is_finite() && !(MIN_RANGE_M..=MAX_RANGE_M).contains(&r);
        if let Some(r) = self
            .landmark_obs
            .iter()
            .map(|(_, z)| z[0])
            .chain(self.target_obs.iter().map(|z| z[0]))
            .find(|&r| bad_range(r))
        {
            return Err(CoreError::invalid(
                "detection range",
                format!("{r} (must be in [{MIN_RANGE_M}, {MAX_RANGE_M}] m)"),
            ));
        }
        if self
            .landmark_obs
            .iter()
            .any(|(_, z)| !(z[0].is_finite() && z[1].is_finite()))
        {
            return Err(CoreError::NonFinite {
                what: "landmark detection",
            });
        }
        if self
            .target_obs
            .iter()
            .any(|z| !(z[0].is_finite() && z[1].is_finite()))
        {
            return Err(CoreError::NonFinite {
                what: "target detection",
            });
        }
        Ok(())
    }
}
