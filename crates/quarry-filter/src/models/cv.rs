//! Constant-velocity and constant-acceleration models.

use super::check_noise;
use crate::FilterError;
use nalgebra::{SMatrix, SVector};
use quarry_core::MotionModel;

/// Process noise of a constant-velocity model (per axis, independent axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CvNoise {
    /// Discrete white-noise acceleration: the acceleration is constant over a step with standard
    /// deviation `sigma_a` (m/s²), `Q = σ_a² [Δ⁴/4, Δ³/2; Δ³/2, Δ²]` per axis (spec 000 §2.6).
    Dwna {
        /// Acceleration standard deviation, m/s².
        sigma_a: f64,
    },
    /// Continuous white-noise acceleration with power spectral density `q` (m²/s³),
    /// `Q = q [Δ³/3, Δ²/2; Δ²/2, Δ]` per axis (the convention of `shared/bench-data`, Stone Soup's
    /// `ConstantVelocity(q)` and filterpy's `Q_continuous_white_noise`).
    Cwna {
        /// Spectral density, m²/s³.
        q: f64,
    },
}

impl CvNoise {
    /// The per-axis `(q_pp, q_pv, q_vv)` entries for a step of `dt`.
    #[inline]
    fn blocks(self, dt: f64) -> (f64, f64, f64) {
        match self {
            CvNoise::Dwna { sigma_a } => {
                let s2 = sigma_a * sigma_a;
                let dt2 = dt * dt;
                (s2 * dt2 * dt2 / 4.0, s2 * dt2 * dt / 2.0, s2 * dt2)
            }
            CvNoise::Cwna { q } => {
                let dt2 = dt * dt;
                (q * dt2 * dt / 3.0, q * dt2 / 2.0, q * dt)
            }
        }
    }

    fn validate(self) -> Result<Self, FilterError> {
        match self {
            CvNoise::Dwna { sigma_a } => check_noise("sigma_a", sigma_a)?,
            CvNoise::Cwna { q } => check_noise("q", q)?,
        }
        Ok(self)
    }
}

/// `F` and `Q` of an `N`-axis constant-velocity model with state `[p_1..p_N, v_1..v_N]`.
#[inline]
fn cv_f_q<const D: usize>(noise: CvNoise, dt: f64) -> (SMatrix<f64, D, D>, SMatrix<f64, D, D>) {
    let n = D / 2;
    let mut f = SMatrix::<f64, D, D>::identity();
    let mut q = SMatrix::<f64, D, D>::zeros();
    let (qpp, qpv, qvv) = noise.blocks(dt);
    for a in 0..n {
        f[(a, n + a)] = dt;
        q[(a, a)] = qpp;
        q[(a, n + a)] = qpv;
        q[(n + a, a)] = qpv;
        q[(n + a, n + a)] = qvv;
    }
    (f, q)
}

#[inline]
fn cv_transition<const D: usize>(x: &SVector<f64, D>, dt: f64) -> SVector<f64, D> {
    let n = D / 2;
    let mut y = *x;
    for a in 0..n {
        y[a] += dt * x[n + a];
    }
    y
}

/// Planar constant velocity, state `[x, y, vx, vy]` (position first).
///
/// `F(Δ) = [I Δ·I; 0 I]`; `Q` from [`CvNoise`]. Control: `()`.
///
/// ```
/// use nalgebra::Vector4;
/// use quarry_core::MotionModel;
/// use quarry_filter::ConstantVelocity2;
/// let cv = ConstantVelocity2::cwna(0.5)?;
/// let x = cv.transition(&Vector4::new(1.0, 2.0, 3.0, 4.0), &(), 0.5);
/// assert_eq!(x, Vector4::new(2.5, 4.0, 3.0, 4.0));
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantVelocity2 {
    /// The process noise.
    pub noise: CvNoise,
}

impl ConstantVelocity2 {
    /// A model with validated noise (finite, non-negative).
    pub fn new(noise: CvNoise) -> Result<Self, FilterError> {
        Ok(Self {
            noise: noise.validate()?,
        })
    }
    /// Discrete white-noise acceleration with standard deviation `sigma_a` (m/s²).
    pub fn dwna(sigma_a: f64) -> Result<Self, FilterError> {
        Self::new(CvNoise::Dwna { sigma_a })
    }
    /// Continuous white-noise acceleration with spectral density `q` (m²/s³).
    pub fn cwna(q: f64) -> Result<Self, FilterError> {
        Self::new(CvNoise::Cwna { q })
    }
}

impl MotionModel<4> for ConstantVelocity2 {
    type Control = ();
    #[inline]
    fn transition(&self, x: &SVector<f64, 4>, _u: &(), dt: f64) -> SVector<f64, 4> {
        cv_transition(x, dt)
    }
    #[inline]
    fn jacobian(&self, _x: &SVector<f64, 4>, _u: &(), dt: f64) -> SMatrix<f64, 4, 4> {
        cv_f_q::<4>(self.noise, dt).0
    }
    #[inline]
    fn process_noise(&self, _x: &SVector<f64, 4>, _u: &(), dt: f64) -> SMatrix<f64, 4, 4> {
        cv_f_q::<4>(self.noise, dt).1
    }
}

/// Spatial constant velocity, state `[x, y, z, vx, vy, vz]`. Control: `()`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantVelocity3 {
    /// The process noise (the same on the three axes).
    pub noise: CvNoise,
}

impl ConstantVelocity3 {
    /// A model with validated noise (finite, non-negative).
    pub fn new(noise: CvNoise) -> Result<Self, FilterError> {
        Ok(Self {
            noise: noise.validate()?,
        })
    }
}

impl MotionModel<6> for ConstantVelocity3 {
    type Control = ();
    #[inline]
    fn transition(&self, x: &SVector<f64, 6>, _u: &(), dt: f64) -> SVector<f64, 6> {
        cv_transition(x, dt)
    }
    #[inline]
    fn jacobian(&self, _x: &SVector<f64, 6>, _u: &(), dt: f64) -> SMatrix<f64, 6, 6> {
        cv_f_q::<6>(self.noise, dt).0
    }
    #[inline]
    fn process_noise(&self, _x: &SVector<f64, 6>, _u: &(), dt: f64) -> SMatrix<f64, 6, 6> {
        cv_f_q::<6>(self.noise, dt).1
    }
}

/// Planar velocity that reverts to zero (an integrated Ornstein–Uhlenbeck process, also called
/// a first-order Gauss–Markov velocity), state `[x, y, vx, vy]`. Control: `()`.
///
/// Per axis, `dv = −v/τ dt + √(2σ_v²/τ) dW` and `dp = v dt`: the velocity keeps a stationary
/// standard deviation `sigma_v` and forgets itself over the correlation time `tau`. Unlike a
/// constant-velocity model, whose position variance grows as Δ³, the position variance of this
/// one grows as Δ² for Δ ≪ τ and only as `2 σ_v² τ Δ` for Δ ≫ τ, so a target that is not seen
/// for a long time stays near where it was seen, as slow ground robots and people do. As
/// τ → ∞ with `2σ_v²/τ = q` it becomes [`ConstantVelocity2::cwna`]`(q)`.
///
/// Exact discretisation with `u = 1 − e^{−Δ/τ}`: `p' = p + τ u v`, `v' = (1 − u) v`,
/// `Q_vv = σ_v² u (2 − u)`, `Q_pv = σ_v² τ u²`, `Q_pp = 2 σ_v² τ² g(Δ/τ)`,
/// `g(x) = x − u − u²/2` (a power series for small `x`, where that difference cancels).
///
/// ```
/// use nalgebra::Vector4;
/// use quarry_core::MotionModel;
/// use quarry_filter::MeanRevertingVelocity2;
/// let m = MeanRevertingVelocity2::new(0.05, 20.0)?;
/// let x = m.transition(&Vector4::new(0.0, 0.0, 0.1, 0.0), &(), 20.0);
/// // the velocity has decayed by e⁻¹; the position moved τ (1 − e⁻¹) v = 1.26 m
/// assert!((x[2] - 0.1 / std::f64::consts::E).abs() < 1e-12);
/// assert!((x[0] - 2.0 * (1.0 - (-1f64).exp())).abs() < 1e-12);
/// // the velocity variance stays at its stationary value σ_v²
/// let q = m.process_noise(&x, &(), 1e3);
/// assert!((q[(2, 2)] - 0.05 * 0.05).abs() < 1e-12);
/// assert!(MeanRevertingVelocity2::new(0.05, 0.0).is_err());
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanRevertingVelocity2 {
    /// Stationary standard deviation of each velocity component, m/s.
    pub sigma_v: f64,
    /// Velocity correlation time τ, s.
    pub tau: f64,
}

impl MeanRevertingVelocity2 {
    /// A model with validated parameters: `sigma_v` finite and ≥ 0, `tau` finite and > 0.
    pub fn new(sigma_v: f64, tau: f64) -> Result<Self, FilterError> {
        check_noise("sigma_v", sigma_v)?;
        if !(tau.is_finite() && tau > 0.0) {
            return Err(quarry_core::CoreError::invalid(
                "tau",
                format!("{tau} (must be finite and > 0)"),
            )
            .into());
        }
        Ok(Self { sigma_v, tau })
    }

    /// `u = 1 − e^{−Δ/τ}` (for Δ ≥ 0; a negative Δ runs the model backwards).
    #[inline]
    fn u(&self, dt: f64) -> f64 {
        -(-dt / self.tau).exp_m1()
    }

    /// The per-axis `(q_pp, q_pv, q_vv)` entries for a step of `dt`.
    fn blocks(&self, dt: f64) -> (f64, f64, f64) {
        let s2 = self.sigma_v * self.sigma_v;
        let x = dt / self.tau;
        let u = self.u(dt);
        let g = if x.abs() < 0.5 {
            // g(x) = Σ_{n≥3} (−1)ⁿ (2 − 2ⁿ⁻¹) xⁿ / n!
            let mut sum = 0.0;
            let mut term = x * x / 2.0; // xⁿ / n! at n = 2
            let mut pow2 = 2.0; // 2ⁿ⁻¹ at n = 2
            let mut sign = 1.0;
            for n in 3..=24 {
                term *= x / n as f64;
                pow2 *= 2.0;
                sign = -sign;
                sum += sign * (2.0 - pow2) * term;
            }
            sum
        } else {
            x - u - 0.5 * u * u
        };
        (
            2.0 * s2 * self.tau * self.tau * g,
            s2 * self.tau * u * u,
            s2 * u * (2.0 - u),
        )
    }
}

impl MotionModel<4> for MeanRevertingVelocity2 {
    type Control = ();
    #[inline]
    fn transition(&self, x: &SVector<f64, 4>, _u: &(), dt: f64) -> SVector<f64, 4> {
        self.jacobian(x, &(), dt) * x
    }
    #[inline]
    fn jacobian(&self, _x: &SVector<f64, 4>, _u: &(), dt: f64) -> SMatrix<f64, 4, 4> {
        let u = self.u(dt);
        let mut f = SMatrix::<f64, 4, 4>::identity();
        for a in 0..2 {
            f[(a, 2 + a)] = self.tau * u;
            f[(2 + a, 2 + a)] = 1.0 - u;
        }
        f
    }
    fn process_noise(&self, _x: &SVector<f64, 4>, _u: &(), dt: f64) -> SMatrix<f64, 4, 4> {
        let (qpp, qpv, qvv) = self.blocks(dt);
        let mut q = SMatrix::<f64, 4, 4>::zeros();
        for a in 0..2 {
            q[(a, a)] = qpp;
            q[(a, 2 + a)] = qpv;
            q[(2 + a, a)] = qpv;
            q[(2 + a, 2 + a)] = qvv;
        }
        q
    }
}

/// Process noise of a constant-acceleration model (per axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CaNoise {
    /// Discrete Wiener-process acceleration (Bar-Shalom, Li, Kirubarajan 2001, §6.3.3): the
    /// acceleration increment over a step has standard deviation `sigma_j` (m/s²),
    /// `Q = σ_j² g gᵀ`, `g = [Δ²/2, Δ, 1]`.
    Dwpa {
        /// Standard deviation of the acceleration increment per step, m/s².
        sigma_j: f64,
    },
    /// Continuous white-noise jerk with spectral density `q` (m²/s⁵):
    /// `Q = q [Δ⁵/20, Δ⁴/8, Δ³/6; Δ⁴/8, Δ³/3, Δ²/2; Δ³/6, Δ²/2, Δ]`.
    Cwnj {
        /// Spectral density, m²/s⁵.
        q: f64,
    },
}

/// Planar constant acceleration, state `[x, y, vx, vy, ax, ay]`. Control: `()`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantAcceleration2 {
    /// The process noise.
    pub noise: CaNoise,
}

impl ConstantAcceleration2 {
    /// A model with validated noise (finite, non-negative).
    pub fn new(noise: CaNoise) -> Result<Self, FilterError> {
        match noise {
            CaNoise::Dwpa { sigma_j } => check_noise("sigma_j", sigma_j)?,
            CaNoise::Cwnj { q } => check_noise("q", q)?,
        }
        Ok(Self { noise })
    }

    /// The per-axis 3×3 block (order p, v, a).
    fn block(&self, dt: f64) -> [[f64; 3]; 3] {
        let (d2, d3) = (dt * dt, dt * dt * dt);
        match self.noise {
            CaNoise::Dwpa { sigma_j } => {
                let g = [d2 / 2.0, dt, 1.0];
                let s2 = sigma_j * sigma_j;
                let mut b = [[0.0; 3]; 3];
                for (i, row) in b.iter_mut().enumerate() {
                    for (j, v) in row.iter_mut().enumerate() {
                        *v = s2 * g[i] * g[j];
                    }
                }
                b
            }
            CaNoise::Cwnj { q } => [
                [q * d3 * d2 / 20.0, q * d2 * d2 / 8.0, q * d3 / 6.0],
                [q * d2 * d2 / 8.0, q * d3 / 3.0, q * d2 / 2.0],
                [q * d3 / 6.0, q * d2 / 2.0, q * dt],
            ],
        }
    }
}

impl MotionModel<6> for ConstantAcceleration2 {
    type Control = ();
    fn transition(&self, x: &SVector<f64, 6>, _u: &(), dt: f64) -> SVector<f64, 6> {
        self.jacobian(x, &(), dt) * x
    }
    fn jacobian(&self, _x: &SVector<f64, 6>, _u: &(), dt: f64) -> SMatrix<f64, 6, 6> {
        let mut f = SMatrix::<f64, 6, 6>::identity();
        for a in 0..2 {
            f[(a, 2 + a)] = dt;
            f[(a, 4 + a)] = dt * dt / 2.0;
            f[(2 + a, 4 + a)] = dt;
        }
        f
    }
    fn process_noise(&self, _x: &SVector<f64, 6>, _u: &(), dt: f64) -> SMatrix<f64, 6, 6> {
        let b = self.block(dt);
        let mut q = SMatrix::<f64, 6, 6>::zeros();
        for a in 0..2 {
            for i in 0..3 {
                for j in 0..3 {
                    q[(2 * i + a, 2 * j + a)] = b[i][j];
                }
            }
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector4;

    #[test]
    fn cv_closed_forms() {
        let dt = 0.3;
        let d = ConstantVelocity2::dwna(0.4).unwrap();
        let q = d.process_noise(&Vector4::zeros(), &(), dt);
        assert!((q[(0, 0)] - 0.16 * dt.powi(4) / 4.0).abs() < 1e-15);
        assert!((q[(0, 2)] - 0.16 * dt.powi(3) / 2.0).abs() < 1e-15);
        assert!((q[(3, 3)] - 0.16 * dt * dt).abs() < 1e-15);
        assert_eq!(q[(0, 1)], 0.0);
        let c = ConstantVelocity2::cwna(0.5).unwrap();
        let q = c.process_noise(&Vector4::zeros(), &(), dt);
        assert!((q[(1, 1)] - 0.5 * dt.powi(3) / 3.0).abs() < 1e-15);
        assert!((q[(1, 3)] - 0.5 * dt * dt / 2.0).abs() < 1e-15);
        assert!((q[(2, 2)] - 0.5 * dt).abs() < 1e-15);
        // F(a) F(b) = F(a + b)
        let fa = c.jacobian(&Vector4::zeros(), &(), 0.2);
        let fb = c.jacobian(&Vector4::zeros(), &(), 0.7);
        let fab = c.jacobian(&Vector4::zeros(), &(), 0.9);
        assert!((fa * fb - fab).amax() < 1e-15);
        assert!(ConstantVelocity2::dwna(f64::NAN).is_err());
        assert!(ConstantVelocity2::cwna(-1.0).is_err());
    }

    #[test]
    fn mean_reverting_velocity_composes_and_tends_to_cwna() {
        let z = Vector4::zeros();
        for (sigma, tau) in [(0.05, 25.0), (1.0, 0.3), (0.2, 1e6)] {
            let m = MeanRevertingVelocity2::new(sigma, tau).unwrap();
            // the series (x < 0.5) and the closed form agree where they meet and compose:
            // F(a + b) = F(b) F(a), Q(a + b) = F(b) Q(a) F(b)ᵀ + Q(b)
            for (a, b) in [
                (0.1, 0.2),
                (0.4 * tau, 0.2 * tau),
                (0.3 * tau, 0.35 * tau),
                (2.0, 7.0),
            ] {
                let (fa, fb, fab) = (
                    m.jacobian(&z, &(), a),
                    m.jacobian(&z, &(), b),
                    m.jacobian(&z, &(), a + b),
                );
                assert!(
                    (fb * fa - fab).amax() <= 1e-12 * fab.amax(),
                    "{sigma} {tau} {a} {b}"
                );
                let (qa, qb, qab) = (
                    m.process_noise(&z, &(), a),
                    m.process_noise(&z, &(), b),
                    m.process_noise(&z, &(), a + b),
                );
                let composed = fb * qa * fb.transpose() + qb;
                assert!(
                    (composed - qab).amax() <= 1e-12 * qab.amax(),
                    "{sigma} {tau} {a} {b}: {composed} vs {qab}"
                );
                assert!(
                    nalgebra::Cholesky::new(qab + SMatrix::<f64, 4, 4>::identity() * 1e-300)
                        .is_some()
                );
            }
        }
        // τ ≫ Δ: the CWNA model with q = 2 σ² / τ
        let m = MeanRevertingVelocity2::new(0.2, 1e6).unwrap();
        let c = ConstantVelocity2::cwna(2.0 * 0.04 / 1e6).unwrap();
        let (q, qc) = (m.process_noise(&z, &(), 3.0), c.process_noise(&z, &(), 3.0));
        assert!((q - qc).amax() <= 1e-5 * qc.amax());
        assert!(MeanRevertingVelocity2::new(f64::NAN, 1.0).is_err());
        assert!(MeanRevertingVelocity2::new(0.1, f64::INFINITY).is_err());
        assert!(MeanRevertingVelocity2::new(-0.1, 1.0).is_err());
    }

    #[test]
    fn ca_transition_and_noise() {
        let ca = ConstantAcceleration2::new(CaNoise::Cwnj { q: 2.0 }).unwrap();
        let x = SVector::<f64, 6>::from_column_slice(&[0.0, 1.0, 1.0, 0.0, 2.0, -2.0]);
        let y = ca.transition(&x, &(), 1.0);
        assert_eq!(y.as_slice(), &[2.0, 0.0, 3.0, -2.0, 2.0, -2.0]);
        let q = ca.process_noise(&x, &(), 1.0);
        assert!((q - q.transpose()).amax() == 0.0);
        assert!((q[(0, 0)] - 0.1).abs() < 1e-15 && (q[(4, 4)] - 2.0).abs() < 1e-15);
        assert_eq!(q[(0, 1)], 0.0);
        // PSD: Cholesky of Q + tiny I succeeds.
        assert!(nalgebra::Cholesky::new(q + SMatrix::<f64, 6, 6>::identity() * 1e-12).is_some());
        let ca = ConstantAcceleration2::new(CaNoise::Dwpa { sigma_j: 1.0 }).unwrap();
        let q = ca.process_noise(&x, &(), 2.0);
        assert!((q[(0, 0)] - 4.0).abs() < 1e-15 && (q[(0, 4)] - 2.0).abs() < 1e-15);
    }
}
