//! Ground-robot models: the unicycle `(v, ω)` and spec 000's bicycle `(V, G)`.

use super::check_noise;
use crate::FilterError;
use nalgebra::{Matrix2, Matrix3, Matrix3x2, SVector, Vector3};
use quarry_core::{CoreError, MotionModel, Pose2, SampledMotion, wrap_angle};
use rand::Rng;
use rand_core::RngCore;
use rand_distr::StandardNormal;

/// `∂(Δx, Δy, Δθ)/∂(v, ω)` of the exact unicycle increment `Pose2::from_unicycle(v, ω, dt)`
/// (spec 001 §2.9), with the series forms below `|ω dt| < 1e-4`.
pub fn unicycle_delta_jacobian(v: f64, omega: f64, dt: f64) -> Matrix3x2<f64> {
    let phi = omega * dt;
    let (dxdv, dydv, dxdw, dydw) = if phi.abs() < 1e-4 {
        (
            dt * (1.0 - phi * phi / 6.0),
            dt * phi / 2.0,
            -v * dt * dt * phi / 3.0,
            v * dt * dt * (0.5 - phi * phi / 8.0),
        )
    } else {
        let (s, c) = phi.sin_cos();
        let half = (phi / 2.0).sin();
        let one_minus_c = 2.0 * half * half;
        let w2 = omega * omega;
        (
            s / omega,
            one_minus_c / omega,
            v * (phi * c - s) / w2,
            v * (phi * s - one_minus_c) / w2,
        )
    };
    Matrix3x2::new(dxdv, dxdw, dydv, dydw, 0.0, dt)
}

/// Unicycle robot, state `[x, y, θ]`, control `(v, ω)` (m/s, rad/s), integrated exactly along the
/// arc ([`Pose2::from_unicycle`]). The process noise is the control noise
/// `diag(σ_v², σ_ω²)` mapped through `∂f/∂u`.
///
/// ```
/// use nalgebra::Vector3;
/// use quarry_core::MotionModel;
/// use quarry_filter::Unicycle;
/// let m = Unicycle::new(0.1, 0.05)?;
/// let x = m.transition(&Vector3::new(0.0, 0.0, 0.0), &(1.0, 0.0), 2.0);
/// assert!((x - Vector3::new(2.0, 0.0, 0.0)).norm() < 1e-12);
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unicycle {
    /// Standard deviation of the speed control, m/s.
    pub sigma_v: f64,
    /// Standard deviation of the turn-rate control, rad/s.
    pub sigma_omega: f64,
}

impl Unicycle {
    /// A model with validated noise (finite, non-negative).
    pub fn new(sigma_v: f64, sigma_omega: f64) -> Result<Self, FilterError> {
        check_noise("sigma_v", sigma_v)?;
        check_noise("sigma_omega", sigma_omega)?;
        Ok(Self {
            sigma_v,
            sigma_omega,
        })
    }

    /// `∂f/∂(v, ω)` at `x`.
    pub fn control_jacobian(&self, x: &SVector<f64, 3>, u: &(f64, f64), dt: f64) -> Matrix3x2<f64> {
        let jd = unicycle_delta_jacobian(u.0, u.1, dt);
        let (s, c) = x[2].sin_cos();
        let rot = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        rot * jd
    }
}

impl MotionModel<3> for Unicycle {
    type Control = (f64, f64);
    fn transition(&self, x: &SVector<f64, 3>, u: &(f64, f64), dt: f64) -> SVector<f64, 3> {
        let p = Pose2 {
            x: x[0],
            y: x[1],
            theta: x[2],
        }
        .compose(&Pose2::from_unicycle(u.0, u.1, dt));
        Vector3::new(p.x, p.y, p.theta)
    }
    fn jacobian(&self, x: &SVector<f64, 3>, u: &(f64, f64), dt: f64) -> Matrix3<f64> {
        let d = Pose2::from_unicycle(u.0, u.1, dt);
        let (s, c) = x[2].sin_cos();
        Matrix3::new(
            1.0,
            0.0,
            -s * d.x - c * d.y,
            0.0,
            1.0,
            c * d.x - s * d.y,
            0.0,
            0.0,
            1.0,
        )
    }
    fn process_noise(&self, x: &SVector<f64, 3>, u: &(f64, f64), dt: f64) -> Matrix3<f64> {
        let j = self.control_jacobian(x, u, dt);
        let su = Matrix2::new(
            self.sigma_v * self.sigma_v,
            0.0,
            0.0,
            self.sigma_omega * self.sigma_omega,
        );
        j * su * j.transpose()
    }
}

impl SampledMotion<3> for Unicycle {
    /// Draws a noisy control `(v + σ_v e₁, ω + σ_ω e₂)` and applies it exactly.
    fn sample(
        &self,
        x: &SVector<f64, 3>,
        u: &(f64, f64),
        dt: f64,
        rng: &mut dyn RngCore,
    ) -> SVector<f64, 3> {
        let e1: f64 = rng.sample(StandardNormal);
        let e2: f64 = rng.sample(StandardNormal);
        self.transition(
            x,
            &(u.0 + self.sigma_v * e1, u.1 + self.sigma_omega * e2),
            dt,
        )
    }
}

/// A lower-triangular `L` with `L Lᵀ = A` for a symmetric positive semi-definite 2×2 `A`
/// (a zero or singular covariance is accepted).
fn psd_sqrt2(a: &Matrix2<f64>) -> Matrix2<f64> {
    let (a11, a21, a22) = (a[(0, 0)], a[(1, 0)], a[(1, 1)]);
    if a11 > 0.0 {
        let l11 = a11.sqrt();
        let l21 = a21 / l11;
        Matrix2::new(l11, 0.0, l21, (a22 - l21 * l21).max(0.0).sqrt())
    } else {
        Matrix2::new(0.0, 0.0, 0.0, a22.max(0.0).sqrt())
    }
}

/// Spec 000's bicycle robot (§2.3): state `[x, y, φ]`, control `(V, G)` = speed (m/s) and
/// steering angle (rad), wheelbase `B`:
///
/// ```text
/// x' = x + V Δ cos(φ + G),   y' = y + V Δ sin(φ + G),   φ' = wrap(φ + V Δ sin(G) / B)
/// ```
///
/// Noise enters through the control: `u ~ N(ũ, Q_u)`. [`SampledMotion::sample`] draws a control
/// and applies the model (the FastSLAM 1.0 proposal); [`MotionModel::process_noise`] is the
/// linearised `J_u Q_u J_uᵀ` for EKF users.
///
/// ```
/// use nalgebra::{Matrix2, Vector3};
/// use quarry_core::MotionModel;
/// use quarry_filter::Bicycle;
/// let b = Bicycle::new(4.0, Matrix2::new(0.09, 0.0, 0.0, 0.0076))?;
/// let x = b.transition(&Vector3::new(0.0, 0.0, 0.0), &(1.0, 0.0), 1.0);
/// assert!((x - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bicycle {
    /// Wheelbase `B`, metres (> 0).
    pub wheelbase: f64,
    /// Control noise covariance `Q_u` of `(V, G)` (symmetric positive semi-definite; zero is
    /// allowed and makes sampling deterministic).
    pub control_noise: Matrix2<f64>,
}

impl Bicycle {
    /// A validated model: `wheelbase` finite and positive, `control_noise` finite, symmetric and
    /// positive semi-definite.
    pub fn new(wheelbase: f64, control_noise: Matrix2<f64>) -> Result<Self, FilterError> {
        if !(wheelbase.is_finite() && wheelbase > 0.0) {
            return Err(CoreError::invalid(
                "wheelbase",
                format!("{wheelbase} (must be finite and > 0)"),
            )
            .into());
        }
        let q = control_noise;
        if !q.iter().all(|v| v.is_finite()) {
            return Err(CoreError::NonFinite {
                what: "control noise",
            }
            .into());
        }
        let tol = 1e-12 * q.amax().max(f64::MIN_POSITIVE);
        let det = q[(0, 0)] * q[(1, 1)] - q[(0, 1)] * q[(1, 0)];
        if (q[(0, 1)] - q[(1, 0)]).abs() > tol
            || q[(0, 0)] < 0.0
            || q[(1, 1)] < 0.0
            || det < -tol * q.amax()
        {
            return Err(CoreError::NotPositiveDefinite {
                what: "control noise (must be symmetric positive semi-definite)",
            }
            .into());
        }
        Ok(Self {
            wheelbase,
            control_noise,
        })
    }

    /// `∂f/∂(V, G)` at `x`.
    pub fn control_jacobian(&self, x: &SVector<f64, 3>, u: &(f64, f64), dt: f64) -> Matrix3x2<f64> {
        let (v, g) = *u;
        let (s, c) = (x[2] + g).sin_cos();
        let (sg, cg) = g.sin_cos();
        Matrix3x2::new(
            dt * c,
            -v * dt * s,
            dt * s,
            v * dt * c,
            dt * sg / self.wheelbase,
            v * dt * cg / self.wheelbase,
        )
    }
}

impl MotionModel<3> for Bicycle {
    type Control = (f64, f64);
    fn transition(&self, x: &SVector<f64, 3>, u: &(f64, f64), dt: f64) -> SVector<f64, 3> {
        let (v, g) = *u;
        let (s, c) = (x[2] + g).sin_cos();
        Vector3::new(
            x[0] + v * dt * c,
            x[1] + v * dt * s,
            wrap_angle(x[2] + v * dt * g.sin() / self.wheelbase),
        )
    }
    fn jacobian(&self, x: &SVector<f64, 3>, u: &(f64, f64), dt: f64) -> Matrix3<f64> {
        let (v, g) = *u;
        let (s, c) = (x[2] + g).sin_cos();
        Matrix3::new(1.0, 0.0, -v * dt * s, 0.0, 1.0, v * dt * c, 0.0, 0.0, 1.0)
    }
    fn process_noise(&self, x: &SVector<f64, 3>, u: &(f64, f64), dt: f64) -> Matrix3<f64> {
        let j = self.control_jacobian(x, u, dt);
        j * self.control_noise * j.transpose()
    }
}

impl SampledMotion<3> for Bicycle {
    /// Draws `u = ũ + e`, `e ~ N(0, Q_u)`, and applies the model.
    fn sample(
        &self,
        x: &SVector<f64, 3>,
        u: &(f64, f64),
        dt: f64,
        rng: &mut dyn RngCore,
    ) -> SVector<f64, 3> {
        let l = psd_sqrt2(&self.control_noise);
        let e = l * nalgebra::Vector2::new(
            rng.sample::<f64, _>(StandardNormal),
            rng.sample::<f64, _>(StandardNormal),
        );
        self.transition(x, &(u.0 + e[0], u.1 + e[1]), dt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use quarry_core::rng::seeded;

    fn fd_jac(
        f: impl Fn(&Vector3<f64>) -> Vector3<f64>,
        x: &Vector3<f64>,
        wrap_last: bool,
    ) -> Matrix3<f64> {
        let h = 1e-6;
        let mut j = Matrix3::zeros();
        for k in 0..3 {
            let mut a = *x;
            let mut b = *x;
            a[k] += h;
            b[k] -= h;
            let mut d = f(&a) - f(&b);
            if wrap_last {
                d[2] = wrap_angle(d[2]);
            }
            j.set_column(k, &(d / (2.0 * h)));
        }
        j
    }

    #[test]
    fn bicycle_straight_and_jacobian() {
        let b = Bicycle::new(4.0, Matrix2::zeros()).unwrap();
        let x = b.transition(
            &Vector3::new(1.0, 1.0, std::f64::consts::FRAC_PI_2),
            &(1.0, 0.0),
            1.0,
        );
        assert!((x - Vector3::new(1.0, 2.0, std::f64::consts::FRAC_PI_2)).norm() < 1e-12);
        let x0 = Vector3::new(0.3, -1.0, 3.1);
        let u = (2.0, 0.3);
        let j = b.jacobian(&x0, &u, 0.2);
        let n = fd_jac(|x| b.transition(x, &u, 0.2), &x0, true);
        assert!((j - n).amax() < 1e-6);
        // heading stays wrapped
        let y = b.transition(&Vector3::new(0.0, 0.0, 3.1), &(3.0, 0.5), 1.0);
        assert!(y[2] > -std::f64::consts::PI && y[2] <= std::f64::consts::PI);
        // zero noise: samples equal the transition
        let mut rng = seeded(1);
        assert_eq!(b.sample(&x0, &u, 0.2, &mut rng), b.transition(&x0, &u, 0.2));
        assert!(Bicycle::new(0.0, Matrix2::zeros()).is_err());
        assert!(Bicycle::new(1.0, Matrix2::new(1.0, 2.0, 2.0, 1.0)).is_err());
    }

    #[test]
    fn bicycle_sample_moments() {
        let q = Matrix2::new(0.09, 0.0, 0.0, 0.0076);
        let b = Bicycle::new(4.0, q).unwrap();
        let mut rng = seeded(3);
        let x0 = Vector3::new(0.0, 0.0, 0.0);
        let n = 20000;
        let mut mean = Vector3::zeros();
        let samples: Vec<_> = (0..n)
            .map(|_| b.sample(&x0, &(2.0, 0.0), 0.025, &mut rng))
            .collect();
        for s in &samples {
            mean += s;
        }
        mean /= n as f64;
        let mut cov = Matrix3::zeros();
        for s in &samples {
            cov += (s - mean) * (s - mean).transpose();
        }
        cov /= n as f64;
        let lin = b.process_noise(&x0, &(2.0, 0.0), 0.025);
        // x variance = (0.025 * 0.3)^2 = 5.625e-5; 2 % sampling error at n = 20000
        assert!(
            (cov[(0, 0)] / lin[(0, 0)] - 1.0).abs() < 0.05,
            "{cov} vs {lin}"
        );
        assert!((cov[(1, 1)] / lin[(1, 1)] - 1.0).abs() < 0.1);
    }

    #[test]
    fn unicycle_jacobians() {
        let m = Unicycle::new(0.2, 0.1).unwrap();
        for &(v, w) in &[(1.0, 0.5), (1.5, 1e-6), (-0.7, -2.0), (0.3, 0.0)] {
            let x0 = Vector3::new(0.5, -0.2, 2.9);
            let dt = 0.1;
            let j = m.jacobian(&x0, &(v, w), dt);
            let n = fd_jac(|x| m.transition(x, &(v, w), dt), &x0, true);
            assert!((j - n).amax() < 1e-6, "{j} {n}");
            // control jacobian
            let jd = unicycle_delta_jacobian(v, w, dt);
            let h = 1e-6;
            let f = |v: f64, w: f64| {
                let d = Pose2::from_unicycle(v, w, dt);
                Vector3::new(d.x, d.y, w * dt)
            };
            let dv = (f(v + h, w) - f(v - h, w)) / (2.0 * h);
            let dw = (f(v, w + h) - f(v, w - h)) / (2.0 * h);
            assert!((jd.column(0) - dv).amax() < 1e-8, "{jd} {dv}");
            assert!((jd.column(1) - dw).amax() < 1e-7, "{jd} {dw}");
        }
    }
}
