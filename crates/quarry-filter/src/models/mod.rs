//! Motion and measurement models implementing quarry-core's [`MotionModel`] and
//! [`MeasurementModel`] traits.
//!
//! State layouts put position first (quarry-core's `StateLayout`): a constant-velocity state is
//! `[x, y, vx, vy]`, not the `[x, vx, y, vy]` order of Stone Soup and filterpy.
//!
//! | model | D | control | notes |
//! |---|---|---|---|
//! | [`ConstantVelocity2`] | 4 | `()` | `[x, y, vx, vy]`, DWNA or CWNA noise ([`CvNoise`]) |
//! | [`MeanRevertingVelocity2`] | 4 | `()` | `[x, y, vx, vy]`, velocity reverting to 0 (integrated Ornstein–Uhlenbeck) |
//! | [`ConstantVelocity3`] | 6 | `()` | `[x, y, z, vx, vy, vz]` |
//! | [`ConstantAcceleration2`] | 6 | `()` | `[x, y, vx, vy, ax, ay]` ([`CaNoise`]) |
//! | [`Unicycle`] | 3 | `(v, ω)` | `[x, y, θ]`, exact arc integration, control noise |
//! | [`Bicycle`] | 3 | `(V, G)` | spec 000 §2.3, noise through the control ([`quarry_core::SampledMotion`]) |
//! | [`EgoCvModel`] | 5 | [`quarry_core::Pose2`] | spec 001 §2.9, target in the moving robot frame |
//!
//! Measurement models: [`Position2`], [`Position3`], [`RangeBearing`] (a point, with
//! [`quarry_core::InverseMeasurement`]) and [`RangeBearingCv`] (the position of a CV state).
//!
//! [`MotionModel`]: quarry_core::MotionModel
//! [`MeasurementModel`]: quarry_core::MeasurementModel

mod cv;
mod ego;
mod measurement;
mod unicycle;

pub use cv::{
    CaNoise, ConstantAcceleration2, ConstantVelocity2, ConstantVelocity3, CvNoise,
    MeanRevertingVelocity2,
};
pub use ego::{EgoCvModel, EgoModel, OdomNoise};
pub use measurement::{Position2, Position3, RangeBearing, RangeBearingCv};
pub use unicycle::{Bicycle, Unicycle, unicycle_delta_jacobian};

use crate::FilterError;
use quarry_core::CoreError;

/// Checks that a noise parameter is finite and non-negative.
pub(crate) fn check_noise(name: &'static str, v: f64) -> Result<(), FilterError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(CoreError::invalid(name, format!("{v} (must be finite and >= 0)")).into())
    }
}
