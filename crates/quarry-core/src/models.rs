//! Motion and measurement models, and gates.

use crate::{CoreError, Gaussian};
use nalgebra::{SMatrix, SVector};
use rand_core::RngCore;

/// A (possibly non-linear) motion model `x' = f(x, u, dt) + w`, `w ~ N(0, Q)`.
///
/// The hot-path methods are infallible; the filters that call them check inputs and results.
pub trait MotionModel<const D: usize> {
    /// The control input: `()` when there is none, `(v, omega)` for a unicycle, a
    /// [`crate::Pose2`] increment for ego-motion compensation.
    type Control;
    /// The mean transition `f(x, u, dt)`.
    fn transition(&self, x: &SVector<f64, D>, u: &Self::Control, dt: f64) -> SVector<f64, D>;
    /// The Jacobian `∂f/∂x` at `x`.
    fn jacobian(&self, x: &SVector<f64, D>, u: &Self::Control, dt: f64) -> SMatrix<f64, D, D>;
    /// The process noise covariance `Q` (symmetric positive semi-definite).
    fn process_noise(&self, x: &SVector<f64, D>, u: &Self::Control, dt: f64) -> SMatrix<f64, D, D>;
}

/// A motion model that can draw a sample of the next state, for particle filters.
///
/// Noise may enter through the control (a robot's odometry), so sampling is not always
/// "transition plus Gaussian".
pub trait SampledMotion<const D: usize>: MotionModel<D> {
    /// Draws `x' ~ p(x' | x, u)`.
    fn sample(
        &self,
        x: &SVector<f64, D>,
        u: &Self::Control,
        dt: f64,
        rng: &mut dyn RngCore,
    ) -> SVector<f64, D>;
}

/// A (possibly non-linear) measurement model `z = h(x) + v`, `v ~ N(0, R)`.
///
/// Sensor poses are fields of the model value, not arguments: build one model per sensor pose
/// (they are a few words and free to construct).
pub trait MeasurementModel<const D: usize, const Z: usize> {
    /// The predicted measurement `h(x)`.
    fn predict(&self, x: &SVector<f64, D>) -> SVector<f64, Z>;
    /// The Jacobian `∂h/∂x` at `x`.
    fn jacobian(&self, x: &SVector<f64, D>) -> SMatrix<f64, Z, D>;
    /// The measurement noise covariance `R` at `x`.
    fn noise(&self, x: &SVector<f64, D>) -> SMatrix<f64, Z, Z>;
    /// The innovation `z - zhat`; models with angles wrap them to (-pi, pi].
    fn residual(&self, z: &SVector<f64, Z>, zhat: &SVector<f64, Z>) -> SVector<f64, Z> {
        z - zhat
    }
}

/// A measurement model that can initialise a state from one measurement (landmark or target
/// initialisation from one detection).
pub trait InverseMeasurement<const D: usize, const Z: usize>: MeasurementModel<D, Z> {
    /// The Gaussian state implied by measurement `z`.
    fn initialise(&self, z: &SVector<f64, Z>) -> Result<Gaussian<D>, CoreError>;
}

/// A validation gate: does measurement `z` fall in the validation region of track `track`?
///
/// Normalised convention: accepted iff [`Gate::distance2`] <= 1 (a chi-square gate returns
/// d²/γ). `dt` is the time since the track's last update, for gates that widen with time.
pub trait Gate<T, Z> {
    /// The normalised squared distance (NaN or +inf means "outside").
    fn distance2(&self, track: &T, z: &Z, dt: f64) -> f64;
    /// True when `z` is inside the gate.
    fn accepts(&self, track: &T, z: &Z, dt: f64) -> bool {
        self.distance2(track, z, dt) <= 1.0
    }
}
