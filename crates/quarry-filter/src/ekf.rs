//! Kalman and extended Kalman filtering on a [`Gaussian`].
//!
//! The free functions [`predict`] and [`update`] are what particle-based trackers call per
//! particle (spec 000); [`Ekf`] wraps them for single-filter users. A Kalman filter is the EKF on
//! linear models: there is no separate type, and on a linear model the EKF equations are exactly
//! the KF's.
//!
//! Numerics: the innovation covariance `S` is Cholesky-factored (never inverted); the gain is
//! `K = P Hᵀ S⁻¹` by two triangular solves; the covariance update is the Joseph form by default
//! (see [`UpdateForm`]). Everything is on nalgebra's static matrices: no heap allocation.
//!
//! Speed: the products run on small fixed-size kernels rather than nalgebra's general `gemm`
//! (which is not inlined at these sizes) and skip the Jacobians' structural zeros (a
//! constant-velocity `F` or a position `H` costs what its non-zeros cost once the model is
//! inlined). The three symmetric results (`F P Fᵀ + Q`, `S = H P Hᵀ + R` and the Joseph
//! posterior) are accumulated on their upper triangle only and mirrored, so they are exactly
//! symmetric with no averaging pass. The Joseph form is evaluated as `P − K Mᵀ + (K S − M) Kᵀ`
//! with `M = P Hᵀ`: algebraically equal to `(I − KH) P (I − KH)ᵀ + K R Kᵀ` for any gain, so it
//! keeps the Joseph form's first-order insensitivity to errors in `K`. [`update`] checks its
//! input and its result once (the factorisation rejects a non-finite `S`) and leaves the
//! innovation's logarithm to [`Innovation::log_likelihood`]. A 4-state CV predict + Joseph
//! update is about 680 instructions (1,700 in the first version; docs/PERFORMANCE.md has the
//! timings against filterpy).
//!
//! Errors never poison a state: the functions take the prior by reference and return a new
//! Gaussian, and [`Ekf`] replaces its state only after a step has succeeded.

// `#[inline(always)]` on the linearisation, the gain and the posterior covariance is measured:
// with `#[inline]` a CV step is 766 instead of 683 instructions (KF) and 1,070 instead of 971
// (range-bearing EKF), callgrind.
#![allow(clippy::inline_always)]

use crate::FilterError;
use crate::small;
use nalgebra::{SMatrix, SVector};
use quarry_core::{Gaussian, MeasurementModel, MotionModel};

/// `ln(2π)`.
const LN_2PI: f64 = 1.837_877_066_409_345_3;

/// How the posterior covariance is computed in a measurement update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum UpdateForm {
    /// `P⁺ = (I − KH) P (I − KH)ᵀ + K R Kᵀ`, then symmetrised. Positive (semi-)definite for any
    /// gain, robust to rounding; the default.
    #[default]
    Joseph,
    /// `P⁺ = (I − KH) P`, the textbook form: cheapest, but rounding can make it asymmetric or
    /// indefinite over long runs.
    Standard,
    /// The standard form followed by `P⁺ ← (P⁺ + P⁺ᵀ) / 2`.
    Symmetrised,
}

/// The innovation statistics of one measurement update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Innovation<const Z: usize> {
    /// The innovation `ν = z ⊖ h(x⁻)` (the model's `residual`, so bearings are wrapped).
    pub nu: SVector<f64, Z>,
    /// The innovation covariance `S = H P⁻ Hᵀ + R` (symmetric).
    pub s: SMatrix<f64, Z, Z>,
    /// The normalised innovation squared `νᵀ S⁻¹ ν` (the squared Mahalanobis distance).
    pub nis: f64,
    /// The diagonal of `S`'s Cholesky factor, for [`Innovation::log_likelihood`].
    chol_diag: [f64; Z],
}

impl<const Z: usize> Innovation<Z> {
    /// `ln det S`.
    pub fn log_det_s(&self) -> f64 {
        small::log_det_from_chol_diag(&self.chol_diag)
    }

    /// The predictive log-likelihood `ln N(ν; 0, S) = −½ (νᵀS⁻¹ν + ln det S + Z ln 2π)` of the
    /// measurement (an RBPF weight). Computed on demand: the logarithm is the one
    /// transcendental function of an update, and most single-filter users never ask for it.
    pub fn log_likelihood(&self) -> f64 {
        -0.5 * (self.nis + self.log_det_s() + Z as f64 * LN_2PI)
    }
}

/// The linearisation of a measurement model at a prior, with `S` factored: what both
/// [`MeasurementPrediction`] and the one-shot [`update`] need.
#[derive(Debug, Clone)]
struct Linearised<const D: usize, const Z: usize> {
    zhat: SVector<f64, Z>,
    h: SMatrix<f64, Z, D>,
    r: SMatrix<f64, Z, Z>,
    s: SMatrix<f64, Z, Z>,
    /// `M = P⁻ Hᵀ`.
    pht: SMatrix<f64, D, Z>,
    chol: small::Chol<Z>,
}

impl<const D: usize, const Z: usize> Linearised<D, Z> {
    /// Errors: [`FilterError::InnovationNotPositiveDefinite`] when `S` is not positive definite
    /// or holds a NaN or an infinity. The Cholesky factorisation rejects every such `S` itself:
    /// a non-finite entry of the (symmetric) `S` reaches a pivot, and a pivot must be finite and
    /// positive, so no separate finiteness sweep is needed.
    #[inline(always)]
    fn new<H>(prior: &Gaussian<D>, model: &H) -> Result<Self, FilterError>
    where
        H: MeasurementModel<D, Z> + ?Sized,
    {
        let x = &prior.mean;
        let zhat = model.predict(x);
        let h = model.jacobian(x);
        let r = model.noise(x);
        let pht = small::mul_tr_sparse(&prior.cov, &h);
        // S = H P Hᵀ + R = Mᵀ Hᵀ + R, upper triangle only, exactly symmetric.
        let s = small::sym_tr_mul_add(&pht, &h, &r);
        let chol = small::Chol::new(&s).ok_or(FilterError::InnovationNotPositiveDefinite)?;
        Ok(Self {
            zhat,
            h,
            r,
            s,
            pht,
            chol,
        })
    }

    /// `K = M S⁻¹`, as `Kᵀ = S⁻¹ Mᵀ` (`S` symmetric).
    #[inline(always)]
    fn gain(&self) -> SMatrix<f64, D, Z> {
        self.chol.solve(&self.pht.transpose()).transpose()
    }
}

/// The posterior covariance for gain `k`, `M = P⁻Hᵀ` and `S`, by `form`.
#[inline(always)]
fn posterior_cov<const D: usize, const Z: usize>(
    prior_cov: &SMatrix<f64, D, D>,
    k: &SMatrix<f64, D, Z>,
    pht: &SMatrix<f64, D, Z>,
    s: &SMatrix<f64, Z, Z>,
    form: UpdateForm,
) -> SMatrix<f64, D, D> {
    match form {
        UpdateForm::Joseph => {
            // (I − KH) P (I − KH)ᵀ + K R Kᵀ = P − K Mᵀ − M Kᵀ + K S Kᵀ for any K: with
            // C = K S − M (the gain's residual, ~0 at the optimum) it is P − K Mᵀ + C Kᵀ,
            // first-order insensitive to errors in K like the textbook congruence.
            let c = small::mul(k, s) - pht;
            small::joseph_sym(prior_cov, k, pht, &c)
        }
        UpdateForm::Standard => prior_cov - small::mul(k, &pht.transpose()),
        UpdateForm::Symmetrised => {
            small::symmetrise(&(prior_cov - small::mul(k, &pht.transpose())))
        }
    }
}

/// Everything an update computes from the prior and the model before it sees a measurement:
/// the predicted measurement, the Jacobian, `S`, its Cholesky factor and the gain.
///
/// Association code evaluates many candidate measurements against one prediction
/// ([`MeasurementPrediction::innovation`], [`MeasurementPrediction::nis`],
/// [`MeasurementPrediction::log_likelihood`]); the PDA update ([`crate::pda`]) shares its gain
/// between all of them.
#[derive(Debug, Clone)]
pub struct MeasurementPrediction<const D: usize, const Z: usize> {
    /// The predicted measurement `ẑ = h(x⁻)`.
    pub zhat: SVector<f64, Z>,
    /// The measurement Jacobian `H = ∂h/∂x` at `x⁻`.
    pub h: SMatrix<f64, Z, D>,
    /// The measurement noise `R` at `x⁻`.
    pub r: SMatrix<f64, Z, Z>,
    /// The innovation covariance `S = H P⁻ Hᵀ + R` (exactly symmetric).
    pub s: SMatrix<f64, Z, Z>,
    /// The Kalman gain `K = P⁻ Hᵀ S⁻¹`.
    pub gain: SMatrix<f64, D, Z>,
    /// `P⁻ Hᵀ`.
    pht: SMatrix<f64, D, Z>,
    chol: small::Chol<Z>,
    /// `−½ (ln det S + Z ln 2π)`.
    log_norm: f64,
}

impl<const D: usize, const Z: usize> MeasurementPrediction<D, Z> {
    /// Linearises `model` at the prior mean and factors `S`.
    ///
    /// Errors: [`FilterError::InnovationNotPositiveDefinite`] when `S` is not finite or not
    /// positive definite (for example a range-bearing model evaluated at zero range);
    /// [`FilterError::NonFiniteResult`] when the predicted measurement or the gain is not finite.
    pub fn new<H>(prior: &Gaussian<D>, model: &H) -> Result<Self, FilterError>
    where
        H: MeasurementModel<D, Z> + ?Sized,
    {
        let lin = Linearised::new(prior, model)?;
        // Every Cholesky pivot is finite and positive, so ln det S is finite (the product form
        // falls back to a sum of logarithms when it under- or overflows).
        let log_det = lin.chol.log_det();
        let gain = lin.gain();
        if !(small::finite(lin.zhat.as_slice()) & small::finite(gain.as_slice())) {
            return Err(FilterError::NonFiniteResult {
                what: "measurement prediction",
            });
        }
        Ok(Self {
            zhat: lin.zhat,
            h: lin.h,
            r: lin.r,
            s: lin.s,
            gain,
            pht: lin.pht,
            chol: lin.chol,
            log_norm: -0.5 * (log_det + Z as f64 * LN_2PI),
        })
    }

    /// The innovation `z ⊖ ẑ` of a measurement under `model` (the model used to build this
    /// prediction).
    ///
    /// Errors: [`FilterError::NonFiniteMeasurement`] if `z` holds a NaN or an infinity.
    pub fn innovation<H>(
        &self,
        model: &H,
        z: &SVector<f64, Z>,
    ) -> Result<SVector<f64, Z>, FilterError>
    where
        H: MeasurementModel<D, Z> + ?Sized,
    {
        if !small::finite(z.as_slice()) {
            return Err(FilterError::NonFiniteMeasurement);
        }
        let nu = model.residual(z, &self.zhat);
        if !small::finite(nu.as_slice()) {
            return Err(FilterError::NonFiniteResult { what: "innovation" });
        }
        Ok(nu)
    }

    /// The normalised innovation squared `νᵀ S⁻¹ ν`.
    pub fn nis(&self, nu: &SVector<f64, Z>) -> f64 {
        self.chol.quad(nu)
    }

    /// `ln N(ν; 0, S)`.
    pub fn log_likelihood(&self, nu: &SVector<f64, Z>) -> f64 {
        self.log_norm - 0.5 * self.nis(nu)
    }

    /// `−½ (ln det S + Z ln 2π)`: the log-likelihood of a zero innovation.
    pub fn log_normaliser(&self) -> f64 {
        self.log_norm
    }

    /// The statistics of innovation `nu`.
    pub fn stats(&self, nu: SVector<f64, Z>) -> Innovation<Z> {
        Innovation {
            nu,
            s: self.s,
            nis: self.nis(&nu),
            chol_diag: self.chol.diag(),
        }
    }

    /// The posterior covariance alone (it does not depend on the innovation).
    pub fn posterior_cov(
        &self,
        prior_cov: &SMatrix<f64, D, D>,
        form: UpdateForm,
    ) -> SMatrix<f64, D, D> {
        posterior_cov(prior_cov, &self.gain, &self.pht, &self.s, form)
    }

    /// The posterior for innovation `nu`, without checks (see [`update`] for the checked path).
    pub fn posterior(
        &self,
        prior: &Gaussian<D>,
        nu: &SVector<f64, Z>,
        form: UpdateForm,
    ) -> Gaussian<D> {
        Gaussian::new_unchecked(
            prior.mean + small::mul_vec(&self.gain, nu),
            self.posterior_cov(&prior.cov, form),
        )
    }
}

fn all_finite<const D: usize>(g: &Gaussian<D>) -> bool {
    small::finite(g.mean.as_slice()) & small::finite(g.cov.as_slice())
}

/// Time update: `x⁻ = f(x, u, dt)`, `P⁻ = F P Fᵀ + Q` (symmetrised).
///
/// Errors: [`FilterError::InvalidTimeStep`] for a negative or non-finite `dt`;
/// [`FilterError::NonFiniteResult`] when the model produces a NaN or an infinity.
///
/// ```
/// use nalgebra::{Matrix4, Vector4};
/// use quarry_core::Gaussian;
/// use quarry_filter::{ekf, ConstantVelocity2};
/// let prior = Gaussian::try_new(Vector4::new(0.0, 0.0, 1.0, 2.0), Matrix4::identity())?;
/// let cv = ConstantVelocity2::dwna(0.1)?;
/// let pred = ekf::predict(&prior, &cv, &(), 0.5)?;
/// assert!((pred.mean - Vector4::new(0.5, 1.0, 1.0, 2.0)).norm() < 1e-12);
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
pub fn predict<const D: usize, M>(
    prior: &Gaussian<D>,
    model: &M,
    u: &M::Control,
    dt: f64,
) -> Result<Gaussian<D>, FilterError>
where
    M: MotionModel<D> + ?Sized,
{
    if !(dt.is_finite() && dt >= 0.0) {
        return Err(FilterError::InvalidTimeStep { dt });
    }
    let x = &prior.mean;
    let f = model.jacobian(x, u, dt);
    let q = model.process_noise(x, u, dt);
    let mean = model.transition(x, u, dt);
    // F P Fᵀ + Q as (P Fᵀ)ᵀ Fᵀ + Q (P is symmetric), upper triangle only, skipping F's
    // structural zeros.
    let pft = small::mul_tr_sparse(&prior.cov, &f);
    let p = small::sym_tr_mul_add(&pft, &f, &q);
    let out = Gaussian::new_unchecked(mean, p);
    if all_finite(&out) {
        Ok(out)
    } else {
        Err(FilterError::NonFiniteResult { what: "prediction" })
    }
}

/// Measurement update of `prior` with measurement `z` under `model`, covariance by `form`.
///
/// Returns the posterior and the innovation statistics (whose `log_likelihood` is the predictive
/// likelihood `ln N(ν; 0, S)` evaluated *before* the update, as an RBPF weight needs).
///
/// Errors: [`FilterError::NonFiniteMeasurement`] (NaN or infinity in `z`),
/// [`FilterError::InnovationNotPositiveDefinite`] (`S` cannot be factored),
/// [`FilterError::NonFiniteResult`] (the model or the arithmetic produced a NaN or an infinity).
///
/// ```
/// use nalgebra::{Matrix4, Vector2, Vector4};
/// use quarry_core::Gaussian;
/// use quarry_filter::{ekf, Position2, UpdateForm};
/// let prior = Gaussian::try_new(Vector4::zeros(), Matrix4::identity())?;
/// let (post, inn) = ekf::update(&prior, &Position2::isotropic(1.0)?, &Vector2::new(2.0, 0.0), UpdateForm::Joseph)?;
/// assert!((post.mean[0] - 1.0).abs() < 1e-12); // equal prior and measurement variances
/// assert!((inn.nis - 2.0).abs() < 1e-12);      // 2² / (1 + 1)
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
pub fn update<const D: usize, const Z: usize, H>(
    prior: &Gaussian<D>,
    model: &H,
    z: &SVector<f64, Z>,
    form: UpdateForm,
) -> Result<(Gaussian<D>, Innovation<Z>), FilterError>
where
    H: MeasurementModel<D, Z> + ?Sized,
{
    if !small::finite(z.as_slice()) {
        return Err(FilterError::NonFiniteMeasurement);
    }
    let lin = Linearised::new(prior, model)?;
    let gain = lin.gain();
    let nu = model.residual(z, &lin.zhat);
    let post = Gaussian::new_unchecked(
        prior.mean + small::mul_vec(&gain, &nu),
        posterior_cov(&prior.cov, &gain, &lin.pht, &lin.s, form),
    );
    // One sweep guards everything upstream: a non-finite ẑ, innovation or gain reaches the
    // posterior mean or covariance (S itself was checked by its factorisation).
    if !all_finite(&post) {
        return Err(FilterError::NonFiniteResult { what: "update" });
    }
    Ok((
        post,
        Innovation {
            nu,
            s: lin.s,
            nis: lin.chol.quad(&nu),
            chol_diag: lin.chol.diag(),
        },
    ))
}

/// A single (extended) Kalman filter: a state, a motion model and a measurement model.
///
/// A Kalman filter is this type on linear models. The state is replaced only when a step
/// succeeds.
///
/// ```
/// use nalgebra::{Matrix4, Vector2, Vector4};
/// use quarry_core::Gaussian;
/// use quarry_filter::{ConstantVelocity2, Ekf, Position2};
/// let x0 = Gaussian::try_new(Vector4::zeros(), Matrix4::identity())?;
/// let mut kf = Ekf::new(x0, ConstantVelocity2::cwna(0.5)?, Position2::isotropic(0.5)?)?;
/// kf.predict(&(), 0.1)?;
/// let inn = kf.update(&Vector2::new(0.1, 0.0))?;
/// assert!(inn.nis >= 0.0);
/// assert!(kf.update(&Vector2::new(f64::NAN, 0.0)).is_err()); // the state is unchanged
/// assert!(kf.mean().iter().all(|v| v.is_finite()));
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Ekf<const D: usize, const Z: usize, F, H> {
    state: Gaussian<D>,
    motion: F,
    measurement: H,
    form: UpdateForm,
}

impl<const D: usize, const Z: usize, F, H> Ekf<D, Z, F, H>
where
    F: MotionModel<D>,
    H: MeasurementModel<D, Z>,
{
    /// A filter from a validated initial state (finite, symmetric positive definite covariance).
    pub fn new(initial: Gaussian<D>, motion: F, measurement: H) -> Result<Self, FilterError> {
        let state = Gaussian::try_new(initial.mean, initial.cov)?;
        Ok(Self {
            state,
            motion,
            measurement,
            form: UpdateForm::Joseph,
        })
    }

    /// Selects the covariance update form (Joseph by default).
    pub fn with_form(mut self, form: UpdateForm) -> Self {
        self.form = form;
        self
    }

    /// The covariance update form in use.
    pub fn form(&self) -> UpdateForm {
        self.form
    }

    /// Time update with control `u` over `dt` seconds.
    pub fn predict(&mut self, u: &F::Control, dt: f64) -> Result<(), FilterError> {
        self.state = predict(&self.state, &self.motion, u, dt)?;
        Ok(())
    }

    /// The prediction over `dt`, without changing the filter (for gating and candidate
    /// generation ahead of the real step).
    pub fn predict_only(&self, u: &F::Control, dt: f64) -> Result<Gaussian<D>, FilterError> {
        predict(&self.state, &self.motion, u, dt)
    }

    /// Measurement update with `z`; returns the innovation statistics.
    pub fn update(&mut self, z: &SVector<f64, Z>) -> Result<Innovation<Z>, FilterError> {
        let (post, inn) = update(&self.state, &self.measurement, z, self.form)?;
        self.state = post;
        Ok(inn)
    }

    /// Measurement update with another measurement model (a second sensor).
    pub fn update_with<const Z2: usize, H2>(
        &mut self,
        model: &H2,
        z: &SVector<f64, Z2>,
    ) -> Result<Innovation<Z2>, FilterError>
    where
        H2: MeasurementModel<D, Z2> + ?Sized,
    {
        let (post, inn) = update(&self.state, model, z, self.form)?;
        self.state = post;
        Ok(inn)
    }

    /// The innovation statistics `z` would have, without updating (gating).
    pub fn innovation(&self, z: &SVector<f64, Z>) -> Result<Innovation<Z>, FilterError> {
        let pred = MeasurementPrediction::new(&self.state, &self.measurement)?;
        let nu = pred.innovation(&self.measurement, z)?;
        Ok(pred.stats(nu))
    }

    /// The state mean.
    pub fn mean(&self) -> &SVector<f64, D> {
        &self.state.mean
    }

    /// The state covariance.
    pub fn cov(&self) -> &SMatrix<f64, D, D> {
        &self.state.cov
    }

    /// The state.
    pub fn state(&self) -> &Gaussian<D> {
        &self.state
    }

    /// Replaces the state (validated: finite, symmetric positive definite).
    pub fn set_state(&mut self, state: Gaussian<D>) -> Result<(), FilterError> {
        self.state = Gaussian::try_new(state.mean, state.cov)?;
        Ok(())
    }

    /// The motion model.
    pub fn motion(&self) -> &F {
        &self.motion
    }

    /// The motion model, mutable (to change noise levels between steps).
    pub fn motion_mut(&mut self) -> &mut F {
        &mut self.motion
    }

    /// The measurement model.
    pub fn measurement(&self) -> &H {
        &self.measurement
    }

    /// The measurement model, mutable (for example to move a sensor pose).
    pub fn measurement_mut(&mut self) -> &mut H {
        &mut self.measurement
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ConstantVelocity2, Position2, RangeBearingCv};
    use nalgebra::{DMatrix, DVector, Matrix2, Matrix4, Vector2, Vector4};
    use proptest::prelude::*;
    use quarry_core::Pose2;
    use quarry_testkit::strategies::{finite_vector, spd_from_rotations};

    fn sym_rel(p: &Matrix4<f64>) -> f64 {
        (p - p.transpose()).amax() / p.amax()
    }

    #[test]
    fn nan_measurement_is_an_error_and_state_is_unchanged() {
        let x0 = Gaussian::try_new(Vector4::new(1.0, 2.0, 0.0, 0.0), Matrix4::identity()).unwrap();
        let mut kf = Ekf::new(
            x0,
            ConstantVelocity2::cwna(0.5).unwrap(),
            Position2::isotropic(0.5).unwrap(),
        )
        .unwrap();
        kf.predict(&(), 0.1).unwrap();
        let before = *kf.state();
        for z in [
            Vector2::new(f64::NAN, 0.0),
            Vector2::new(0.0, f64::INFINITY),
        ] {
            assert_eq!(kf.update(&z), Err(FilterError::NonFiniteMeasurement));
            assert_eq!(*kf.state(), before);
        }
        assert!(matches!(
            kf.predict(&(), f64::NAN),
            Err(FilterError::InvalidTimeStep { .. })
        ));
        assert!(matches!(
            kf.predict(&(), -0.1),
            Err(FilterError::InvalidTimeStep { .. })
        ));
        assert_eq!(*kf.state(), before);
    }

    #[test]
    fn innovation_not_positive_definite_is_typed() {
        // Zero prior covariance and an (unvalidated) zero R: S = 0.
        let prior = Gaussian::new_unchecked(Vector4::new(1.0, 1.0, 0.0, 0.0), Matrix4::zeros());
        let m = Position2 {
            r: Matrix2::zeros(),
        };
        assert_eq!(
            update(&prior, &m, &Vector2::new(0.0, 0.0), UpdateForm::Joseph).map(|_| ()),
            Err(FilterError::InnovationNotPositiveDefinite)
        );
        // Range-bearing at zero range: the Jacobian is NaN, S is not finite.
        let prior = Gaussian::new_unchecked(Vector4::zeros(), Matrix4::identity());
        let rb = RangeBearingCv::new(Pose2::identity(), 0.5, 0.01).unwrap();
        assert_eq!(
            update(&prior, &rb, &Vector2::new(1.0, 0.0), UpdateForm::Joseph).map(|_| ()),
            Err(FilterError::InnovationNotPositiveDefinite)
        );
        // Indefinite R.
        let m = Position2 {
            r: Matrix2::new(-5.0, 0.0, 0.0, 1.0),
        };
        let prior = Gaussian::new_unchecked(Vector4::zeros(), Matrix4::identity());
        assert_eq!(
            update(&prior, &m, &Vector2::new(0.0, 0.0), UpdateForm::Joseph).map(|_| ()),
            Err(FilterError::InnovationNotPositiveDefinite)
        );
    }

    #[test]
    fn scalar_update_numbers() {
        // 1-D check via the position model on D = 2: prior var 4, R = 1, z - x = 5.
        let prior =
            Gaussian::try_new(Vector2::new(0.0, 0.0), Matrix2::new(4.0, 0.0, 0.0, 4.0)).unwrap();
        let m = Position2::isotropic(1.0).unwrap();
        for form in [
            UpdateForm::Joseph,
            UpdateForm::Standard,
            UpdateForm::Symmetrised,
        ] {
            let (post, inn) = update(&prior, &m, &Vector2::new(5.0, 0.0), form).unwrap();
            assert!((post.mean[0] - 4.0).abs() < 1e-12); // K = 0.8
            assert!((post.cov[(0, 0)] - 0.8).abs() < 1e-12);
            assert!((inn.nis - 5.0).abs() < 1e-12); // 25 / 5
            let ll = -0.5 * (5.0 + (25.0f64).ln() + 2.0 * (2.0 * std::f64::consts::PI).ln());
            assert!((inn.log_likelihood() - ll).abs() < 1e-12);
        }
    }

    #[test]
    fn prediction_reuse_matches_update() {
        let prior = Gaussian::try_new(
            Vector4::new(10.0, 5.0, 1.0, -1.0),
            spd_from_rotations(&[0.3, 0.1, 0.5, 0.2, 0.9, 1.1], &[0.0, -1.0, 0.5, -0.5]),
        )
        .unwrap();
        let rb = RangeBearingCv::new(Pose2::new(1.0, -1.0, 0.4), 0.5, 0.01).unwrap();
        let z = Vector2::new(10.0, 0.1);
        let (post, inn) = update(&prior, &rb, &z, UpdateForm::Joseph).unwrap();
        let pred = MeasurementPrediction::new(&prior, &rb).unwrap();
        let nu = pred.innovation(&rb, &z).unwrap();
        assert_eq!(nu, inn.nu);
        assert!((pred.nis(&nu) - inn.nis).abs() < 1e-12);
        let g = Gaussian::try_new(Vector2::zeros(), inn.s).unwrap();
        assert!((g.log_pdf(&nu).unwrap() - inn.log_likelihood()).abs() < 1e-10);
        assert!((pred.posterior(&prior, &nu, UpdateForm::Joseph).mean - post.mean).norm() < 1e-12);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// Spec 000 §6.1 tests 6 and 7: symmetric to 1e-12 relative, Cholesky succeeds,
        /// det and trace do not grow in an update; over random predict/update sequences.
        #[test]
        fn covariance_stays_spd(
            angles in proptest::array::uniform6(-3.2..3.2f64),
            log_eigs in proptest::array::uniform4(-4.0..4.0f64),
            steps in proptest::collection::vec((0.01..0.5f64, -20.0..20.0f64, -20.0..20.0f64, any::<bool>(), any::<bool>()), 1..40),
        ) {
            let p0 = spd_from_rotations(&angles, &log_eigs);
            let mut g = Gaussian::try_new(Vector4::new(8.0, -6.0, 1.0, 0.5), p0).unwrap();
            let cv = ConstantVelocity2::dwna(0.4).unwrap();
            let pos = Position2::isotropic(0.3).unwrap();
            let rb = RangeBearingCv::new(Pose2::new(0.0, 0.0, 0.3), 0.2, 0.02).unwrap();
            for (dt, zx, zy, use_rb, skip) in steps {
                g = predict(&g, &cv, &(), dt).unwrap();
                prop_assert!(sym_rel(&g.cov) <= 1e-12);
                prop_assert!(g.cholesky().is_ok());
                if skip { continue; }
                let before = g;
                let res = if use_rb {
                    let z = rb.predict(&g.mean) + Vector2::new(zx * 0.01, zy * 0.001);
                    update(&g, &rb, &z, UpdateForm::Joseph)
                } else {
                    update(&g, &pos, &(g.mean.fixed_rows::<2>(0) + Vector2::new(zx, zy)), UpdateForm::Joseph)
                };
                let (post, inn) = res.unwrap();
                prop_assert!(inn.nis >= 0.0);
                prop_assert!(sym_rel(&post.cov) <= 1e-12);
                prop_assert!(post.cholesky().is_ok());
                prop_assert!(post.cov.determinant() <= before.cov.determinant() * (1.0 + 1e-9));
                prop_assert!(post.cov.trace() <= before.cov.trace() * (1.0 + 1e-12));
                g = post;
            }
        }

        /// On a linear-Gaussian problem the KF's final state equals the last block of the batch
        /// least-squares (MAP) estimate of the whole trajectory, and its covariance equals the
        /// last block of the inverse information matrix.
        #[test]
        fn kf_equals_batch_least_squares(
            zs in proptest::collection::vec((-5.0..5.0f64, -5.0..5.0f64, 0.05..1.0f64), 1..12),
            m0 in finite_vector::<4>(-2.0..2.0f64),
            q in 0.01..2.0f64,
            sigma in 0.1..2.0f64,
        ) {
            let cv = ConstantVelocity2::cwna(q).unwrap();
            let pos = Position2::isotropic(sigma).unwrap();
            let p0 = Matrix4::from_diagonal(&Vector4::new(2.0, 3.0, 0.5, 0.7));
            let mut g = Gaussian::try_new(m0, p0).unwrap();
            for &(zx, zy, dt) in &zs {
                g = predict(&g, &cv, &(), dt).unwrap();
                g = update(&g, &pos, &Vector2::new(zx, zy), UpdateForm::Joseph).unwrap().0;
            }
            // Batch: unknowns x_0..x_n (x_0 is the prior time), stacked.
            let n = zs.len();
            let dim = 4 * (n + 1);
            let mut info = DMatrix::<f64>::zeros(dim, dim);
            let mut eta = DVector::<f64>::zeros(dim);
            let add = |info: &mut DMatrix<f64>, eta: &mut DVector<f64>, a: &DMatrix<f64>, w: &DMatrix<f64>, b: &DVector<f64>| {
                // residual a X - b with weight w (inverse covariance)
                *info += a.transpose() * w * a;
                *eta += a.transpose() * w * b;
            };
            let p0_inv = DMatrix::from_column_slice(4, 4, p0.try_inverse().unwrap().as_slice());
            let mut a = DMatrix::<f64>::zeros(4, dim);
            a.view_mut((0, 0), (4, 4)).fill_with_identity();
            add(&mut info, &mut eta, &a, &p0_inv, &DVector::from_column_slice(m0.as_slice()));
            let r_inv = DMatrix::<f64>::identity(2, 2) / (sigma * sigma);
            for (k, &(zx, zy, dt)) in zs.iter().enumerate() {
                let f = cv.jacobian(&Vector4::zeros(), &(), dt);
                let qk = cv.process_noise(&Vector4::zeros(), &(), dt);
                let q_inv = DMatrix::from_column_slice(4, 4, qk.try_inverse().unwrap().as_slice());
                let mut a = DMatrix::<f64>::zeros(4, dim);
                a.view_mut((0, 4 * (k + 1)), (4, 4)).fill_with_identity();
                a.view_mut((0, 4 * k), (4, 4)).copy_from(&(-DMatrix::from_column_slice(4, 4, f.as_slice())));
                add(&mut info, &mut eta, &a, &q_inv, &DVector::zeros(4));
                let mut h = DMatrix::<f64>::zeros(2, dim);
                h[(0, 4 * (k + 1))] = 1.0;
                h[(1, 4 * (k + 1) + 1)] = 1.0;
                add(&mut info, &mut eta, &h, &r_inv, &DVector::from_column_slice(&[zx, zy]));
            }
            let chol = info.cholesky().unwrap();
            let x = chol.solve(&eta);
            let cov = chol.inverse();
            let scale = g.cov.amax();
            for i in 0..4 {
                prop_assert!((x[4 * n + i] - g.mean[i]).abs() < 1e-7 * (1.0 + g.mean[i].abs()), "mean {i}: {} vs {}", x[4 * n + i], g.mean[i]);
                for j in 0..4 {
                    prop_assert!((cov[(4 * n + i, 4 * n + j)] - g.cov[(i, j)]).abs() < 1e-7 * scale);
                }
            }
        }

        /// The three update forms agree on well-conditioned problems.
        #[test]
        fn update_forms_agree(angles in proptest::array::uniform6(-3.2..3.2f64), log_eigs in proptest::array::uniform4(-1.0..1.0f64), zx in -3.0..3.0f64) {
            let g = Gaussian::try_new(Vector4::zeros(), spd_from_rotations(&angles, &log_eigs)).unwrap();
            let pos = Position2::isotropic(0.7).unwrap();
            let z = Vector2::new(zx, 1.0);
            let (a, _) = update(&g, &pos, &z, UpdateForm::Joseph).unwrap();
            let (b, _) = update(&g, &pos, &z, UpdateForm::Standard).unwrap();
            let (c, _) = update(&g, &pos, &z, UpdateForm::Symmetrised).unwrap();
            prop_assert!((a.cov - b.cov).amax() < 1e-10 && (a.cov - c.cov).amax() < 1e-10);
            prop_assert!((a.mean - b.mean).amax() < 1e-12);
            prop_assert!(sym_rel(&c.cov) == 0.0);
        }
    }
}
