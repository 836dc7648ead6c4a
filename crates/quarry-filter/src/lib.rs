//! # quarry-filter
//!
//! Kalman, extended Kalman and particle filters over quarry-core's [`MotionModel`] and
//! [`MeasurementModel`] traits, the models the four quarry trackers need, and the
//! Rao-Blackwellized building blocks of a FastSLAM-style particle filter.
//!
//! ```
//! use nalgebra::{Matrix4, Vector2, Vector4};
//! use quarry_core::Gaussian;
//! use quarry_filter::{ConstantVelocity2, Ekf, Position2};
//!
//! // A constant-velocity Kalman filter, state [x, y, vx, vy], position measurements.
//! let x0 = Gaussian::try_new(Vector4::new(0.0, 0.0, 1.0, 0.0), Matrix4::identity())?;
//! let mut kf = Ekf::new(x0, ConstantVelocity2::cwna(0.5)?, Position2::isotropic(0.5)?)?;
//! for k in 1..=20 {
//!     kf.predict(&(), 0.1)?;
//!     kf.update(&Vector2::new(0.1 * k as f64, 0.0))?;   // Joseph-form update
//! }
//! assert!((kf.mean()[0] - 2.0).abs() < 0.1 && (kf.mean()[2] - 1.0).abs() < 0.2);
//!
//! // A NaN measurement is an error and leaves the state untouched.
//! let before = *kf.state();
//! assert!(kf.update(&Vector2::new(f64::NAN, 0.0)).is_err());
//! assert_eq!(*kf.state(), before);
//! # Ok::<(), quarry_filter::FilterError>(())
//! ```
//!
//! ## Contents
//! - [`ekf`]: [`ekf::predict`] / [`ekf::update`] on a [`Gaussian`], the [`Ekf`] wrapper,
//!   [`UpdateForm`] (Joseph by default), [`Innovation`] statistics, and
//!   [`ekf::MeasurementPrediction`] for evaluating many measurements against one prediction.
//! - [`models`]: constant velocity (2-D, 3-D), constant acceleration, unicycle, spec 000's
//!   bicycle, spec 001's ego-motion model; position and range-bearing measurements.
//! - [`pda`]: the PDA combined-innovation update with the spread-of-innovations term.
//! - [`particles`]: log-domain weights, effective sample size, systematic / stratified /
//!   multinomial / residual resampling.
//! - [`store`]: per-particle landmark maps, [`store::PersistentStore`] (Arc-shared tree, O(1)
//!   copy, O(log M) write) and [`store::VecStore`].
//! - [`rbpf`]: the FastSLAM 1.0 per-particle landmark kernels ([`rbpf::fastslam1`]).
//! - [`smoother`]: batch smoothing of a landmark-SLAM recording (all poses, landmarks and the
//!   odometry calibration at once; Levenberg–Marquardt, Huber detections).
//!
//! ## Features
//!
//! None: the crate has no optional parts, and it uses quarry-core without quarry-core's default
//! features (`serde`, `rng`), so `--no-default-features` and the default build are the same lean
//! build. Every sampler takes any `rand_core::RngCore`; enable `quarry-core/rng` for quarry's
//! seeded generator and `quarry-core/serde` to (de)serialise the [`Gaussian`]s it returns.
//!
//! [`Gaussian`]: quarry_core::Gaussian
//! [`MotionModel`]: quarry_core::MotionModel
//! [`MeasurementModel`]: quarry_core::MeasurementModel

pub mod ekf;
mod error;
pub mod models;
pub mod particles;
pub mod pda;
pub mod rbpf;
mod small;
pub mod smoother;
pub mod store;

pub use ekf::{Ekf, Innovation, UpdateForm};
pub use error::FilterError;
pub use models::{
    Bicycle, CaNoise, ConstantAcceleration2, ConstantVelocity2, ConstantVelocity3, CvNoise,
    EgoCvModel, EgoModel, MeanRevertingVelocity2, OdomNoise, Position2, Position3, RangeBearing,
    RangeBearingCv, Unicycle,
};
