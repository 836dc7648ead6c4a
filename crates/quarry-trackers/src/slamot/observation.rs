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

impl SlamotObservation {
    /// Checks that every landmark and target detection is finite with a range > 0 (what both
    /// the RBPF and the EKF-SLAMOT baseline require before an observation epoch; a zero range
    /// is no detection, and readers skip it: `quarry_data::mrclam` counts them).
    pub fn check_detections(&self) -> Result<(), CoreError> {
        let bad_range = |r: f64| r.is_finite() && r <= 0.0;
        if let Some(r) = self
            .landmark_obs
            .iter()
            .map(|(_, z)| z[0])
            .chain(self.target_obs.iter().map(|z| z[0]))
            .find(|&r| bad_range(r))
        {
            return Err(CoreError::invalid(
                "detection range",
                format!("{r} (must be > 0)"),
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
