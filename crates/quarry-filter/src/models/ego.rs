//! Spec 001's ego-motion compensated constant-velocity model (the MEKF transition).

use super::{check_noise, unicycle_delta_jacobian};
use crate::FilterError;
use nalgebra::{Matrix3, SMatrix, SVector};
use quarry_core::{CoreError, MotionModel, Pose2};

/// Which form of the ego-motion transition [`EgoCvModel`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum EgoModel {
    /// Spec 001 eq. (11′), the corrected form (default): the exact inverse of the robot's rigid
    /// motion applied to a target moving at constant ground velocity,
    /// `p' = Rᵀ(p + ṗΔt − Δp)`, `z' = z`, `ṗ' = Rᵀṗ`.
    #[default]
    Compensated,
    /// The paper's eq. (11) as printed, for ablation only: `p' = Rᵀ(p − Δp)` (no `ṗΔt` term),
    /// `ẋ' = cẋ + sẏ − v`, `ẏ' = sẋ + cẏ`. With a pose-increment control the robot speed is taken
    /// as `v = Δx / Δt` (the forward component of the increment; 0 when `Δt = 0`), a choice the
    /// spec leaves open.
    PaperLiteral,
}

/// Odometry noise: the covariance `Σ_Δ` of the pose increment `(Δx, Δy, Δθ)` over one step,
/// added to the process noise as `J_Δ Σ_Δ J_Δᵀ` (spec 001 §2.9).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdomNoise {
    /// Covariance of `(Δx, Δy, Δθ)` (symmetric positive semi-definite).
    pub cov: Matrix3<f64>,
}

impl OdomNoise {
    /// The increment covariance implied by velocity-control noise `diag(σ_v², σ_ω²)` for a step of
    /// the unicycle `(v, ω, Δt)`, through `∂Δ/∂(v, ω)` (spec 001 §2.9, with the small-angle series).
    pub fn from_velocity(v: f64, omega: f64, dt: f64, sigma_v: f64, sigma_omega: f64) -> Self {
        let j = unicycle_delta_jacobian(v, omega, dt);
        let s = nalgebra::Matrix2::new(sigma_v * sigma_v, 0.0, 0.0, sigma_omega * sigma_omega);
        Self {
            cov: j * s * j.transpose(),
        }
    }
}

/// The MEKF transition of spec 001 §2.9: a target at constant ground velocity, observed from a
/// moving robot, in the robot's frame.
///
/// State `[x, y, z, ẋ, ẏ]` (position in the robot frame, `z` the height; ground velocity in the
/// current robot frame). Control: the robot's pose increment `Δ = (Δx, Δy, Δθ)` over the step, in
/// the frame of the start pose (convert velocity controls with [`Pose2::from_unicycle`], eq. A3).
///
/// Process noise (A4): `Q = G σ_w² I₂ Gᵀ + diag(0, 0, σ_h² Δt, 0, 0) (+ J_Δ Σ_Δ J_Δᵀ)`, with
/// `G = [Δt²/2 I₂; 0; Δt I₂]` (white horizontal acceleration) and a random walk on the height.
///
/// ```
/// use nalgebra::SVector;
/// use quarry_core::{MotionModel, Pose2};
/// use quarry_filter::EgoCvModel;
/// let m = EgoCvModel::new(0.5, 0.01)?;
/// // The robot drives 1 m forward: a static target 3 m ahead is now 2 m ahead.
/// let x = SVector::<f64, 5>::from_column_slice(&[3.0, 0.0, 1.0, 0.0, 0.0]);
/// let y = m.transition(&x, &Pose2::new(1.0, 0.0, 0.0), 0.1);
/// assert!((y[0] - 2.0).abs() < 1e-12);
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoCvModel {
    /// White horizontal acceleration standard deviation σ_w, m/s².
    pub sigma_w: f64,
    /// Height random-walk standard deviation σ_h, m/√s.
    pub sigma_h: f64,
    /// Corrected (default) or the paper's literal transition.
    pub variant: EgoModel,
    /// Optional odometry noise on the increment.
    pub odom_noise: Option<OdomNoise>,
}

impl EgoCvModel {
    /// The corrected model without odometry noise; `sigma_w`, `sigma_h` finite and non-negative.
    pub fn new(sigma_w: f64, sigma_h: f64) -> Result<Self, FilterError> {
        check_noise("sigma_w", sigma_w)?;
        check_noise("sigma_h", sigma_h)?;
        Ok(Self {
            sigma_w,
            sigma_h,
            variant: EgoModel::Compensated,
            odom_noise: None,
        })
    }

    /// Selects the transition variant.
    pub fn with_variant(mut self, variant: EgoModel) -> Self {
        self.variant = variant;
        self
    }

    /// Adds odometry noise (validated: finite, symmetric, non-negative diagonal).
    pub fn with_odom_noise(mut self, noise: OdomNoise) -> Result<Self, FilterError> {
        let c = noise.cov;
        if !c.iter().all(|v| v.is_finite()) {
            return Err(CoreError::NonFinite {
                what: "odometry noise",
            }
            .into());
        }
        if (c - c.transpose()).amax() > 1e-12 * c.amax() || c.diagonal().iter().any(|&v| v < 0.0) {
            return Err(CoreError::NotPositiveDefinite {
                what: "odometry noise (must be symmetric positive semi-definite)",
            }
            .into());
        }
        self.odom_noise = Some(noise);
        Ok(self)
    }

    /// `∂f/∂(Δx, Δy, Δθ)` at `x` (spec 001 §2.9, "control Jacobian").
    pub fn delta_jacobian(&self, x: &SVector<f64, 5>, d: &Pose2, dt: f64) -> SMatrix<f64, 5, 3> {
        let (s, c) = d.theta.sin_cos();
        let mut j = SMatrix::<f64, 5, 3>::zeros();
        // -Rᵀ on the position rows
        j[(0, 0)] = -c;
        j[(0, 1)] = -s;
        j[(1, 0)] = s;
        j[(1, 1)] = -c;
        let (ax, ay) = match self.variant {
            EgoModel::Compensated => (x[0] + dt * x[3] - d.x, x[1] + dt * x[4] - d.y),
            EgoModel::PaperLiteral => (x[0] - d.x, x[1] - d.y),
        };
        // R'ᵀ a with R'ᵀ = [[-s, c], [-c, -s]]
        j[(0, 2)] = -s * ax + c * ay;
        j[(1, 2)] = -c * ax - s * ay;
        match self.variant {
            EgoModel::Compensated => {
                j[(3, 2)] = -s * x[3] + c * x[4];
                j[(4, 2)] = -c * x[3] - s * x[4];
            }
            EgoModel::PaperLiteral => {
                if dt > 0.0 {
                    j[(3, 0)] = -1.0 / dt;
                }
                j[(3, 2)] = -s * x[3] + c * x[4];
                j[(4, 2)] = c * x[3] - s * x[4];
            }
        }
        j
    }
}

impl MotionModel<5> for EgoCvModel {
    type Control = Pose2;

    fn transition(&self, x: &SVector<f64, 5>, d: &Pose2, dt: f64) -> SVector<f64, 5> {
        let (s, c) = d.theta.sin_cos();
        match self.variant {
            EgoModel::Compensated => {
                let ax = x[0] + dt * x[3] - d.x;
                let ay = x[1] + dt * x[4] - d.y;
                SVector::<f64, 5>::new(
                    c * ax + s * ay,
                    -s * ax + c * ay,
                    x[2],
                    c * x[3] + s * x[4],
                    -s * x[3] + c * x[4],
                )
            }
            EgoModel::PaperLiteral => {
                let ax = x[0] - d.x;
                let ay = x[1] - d.y;
                let v = if dt > 0.0 { d.x / dt } else { 0.0 };
                SVector::<f64, 5>::new(
                    c * ax + s * ay,
                    -s * ax + c * ay,
                    x[2],
                    c * x[3] + s * x[4] - v,
                    s * x[3] + c * x[4],
                )
            }
        }
    }

    fn jacobian(&self, _x: &SVector<f64, 5>, d: &Pose2, dt: f64) -> SMatrix<f64, 5, 5> {
        let (s, c) = d.theta.sin_cos();
        match self.variant {
            EgoModel::Compensated => SMatrix::<f64, 5, 5>::from_row_slice(&[
                c,
                s,
                0.0,
                c * dt,
                s * dt, //
                -s,
                c,
                0.0,
                -s * dt,
                c * dt, //
                0.0,
                0.0,
                1.0,
                0.0,
                0.0, //
                0.0,
                0.0,
                0.0,
                c,
                s, //
                0.0,
                0.0,
                0.0,
                -s,
                c,
            ]),
            EgoModel::PaperLiteral => SMatrix::<f64, 5, 5>::from_row_slice(&[
                c, s, 0.0, 0.0, 0.0, //
                -s, c, 0.0, 0.0, 0.0, //
                0.0, 0.0, 1.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, c, s, //
                0.0, 0.0, 0.0, s, c,
            ]),
        }
    }

    fn process_noise(&self, x: &SVector<f64, 5>, d: &Pose2, dt: f64) -> SMatrix<f64, 5, 5> {
        let s2 = self.sigma_w * self.sigma_w;
        let dt2 = dt * dt;
        let (qpp, qpv, qvv) = (s2 * dt2 * dt2 / 4.0, s2 * dt2 * dt / 2.0, s2 * dt2);
        let mut q = SMatrix::<f64, 5, 5>::zeros();
        for a in 0..2 {
            q[(a, a)] = qpp;
            q[(a, 3 + a)] = qpv;
            q[(3 + a, a)] = qpv;
            q[(3 + a, 3 + a)] = qvv;
        }
        q[(2, 2)] = self.sigma_h * self.sigma_h * dt;
        if let Some(odom) = &self.odom_noise {
            let j = self.delta_jacobian(x, d, dt);
            q += j * odom.cov * j.transpose();
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn x5(v: [f64; 5]) -> SVector<f64, 5> {
        SVector::<f64, 5>::from_column_slice(&v)
    }

    #[test]
    fn unit_checks() {
        let m = EgoCvModel::new(0.0, 0.0).unwrap();
        let y = m.transition(
            &x5([1.0, 0.0, 0.0, 0.0, 0.0]),
            &Pose2::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
            0.1,
        );
        assert!((y - x5([0.0, -1.0, 0.0, 0.0, 0.0])).norm() < 1e-12);
        let y = m.transition(
            &x5([3.0, 0.0, 0.0, 0.0, 0.0]),
            &Pose2::new(1.0, 0.0, 0.0),
            0.1,
        );
        assert!((y - x5([2.0, 0.0, 0.0, 0.0, 0.0])).norm() < 1e-12);
    }

    #[test]
    fn rigid_inverse_and_composition() {
        let m = EgoCvModel::new(0.3, 0.01).unwrap();
        let p = x5([2.0, -1.5, 1.1, 0.0, 0.0]);
        let d1 = Pose2::new(0.3, 0.1, 0.4);
        let d2 = Pose2::new(-0.2, 0.5, -1.3);
        let y = m.transition(&p, &d1, 0.1);
        // R(Δθ) p' + Δp = p
        let back = d1.apply(&quarry_core::Point2::new(y[0], y[1]));
        assert!((back.x - p[0]).abs() < 1e-12 && (back.y - p[1]).abs() < 1e-12);
        let two = m.transition(&y, &d2, 0.1);
        let once = m.transition(&p, &d1.compose(&d2), 0.2);
        assert!((two - once).norm() < 1e-12, "{two} {once}");
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let x = x5([2.0, -1.5, 1.1, 0.7, -0.4]);
        let h = 1e-6;
        for variant in [EgoModel::Compensated, EgoModel::PaperLiteral] {
            let odom = OdomNoise::from_velocity(1.0, 0.5, 0.1, 0.1, 0.05);
            let m = EgoCvModel::new(0.3, 0.01)
                .unwrap()
                .with_variant(variant)
                .with_odom_noise(odom)
                .unwrap();
            for d in [
                Pose2::new(0.1, 0.02, 0.3),
                Pose2::new(0.05, 0.0, 5e-5),
                Pose2::new(-0.1, 0.03, -2.0),
            ] {
                let dt = 0.1;
                let f = m.jacobian(&x, &d, dt);
                for k in 0..5 {
                    let mut a = x;
                    let mut b = x;
                    a[k] += h;
                    b[k] -= h;
                    let col = (m.transition(&a, &d, dt) - m.transition(&b, &d, dt)) / (2.0 * h);
                    for i in 0..5 {
                        assert!(
                            (f[(i, k)] - col[i]).abs() <= 1e-6 * f[(i, k)].abs() + 1e-9,
                            "{variant:?} F {i} {k}"
                        );
                    }
                }
                let jd = m.delta_jacobian(&x, &d, dt);
                for k in 0..3 {
                    let mut a = d;
                    let mut b = d;
                    match k {
                        0 => {
                            a.x += h;
                            b.x -= h;
                        }
                        1 => {
                            a.y += h;
                            b.y -= h;
                        }
                        _ => {
                            a.theta += h;
                            b.theta -= h;
                        }
                    }
                    let col = (m.transition(&x, &a, dt) - m.transition(&x, &b, dt)) / (2.0 * h);
                    for i in 0..5 {
                        assert!(
                            (jd[(i, k)] - col[i]).abs() <= 1e-6 * jd[(i, k)].abs() + 1e-9,
                            "{variant:?} J {i} {k}"
                        );
                    }
                }
                let q = m.process_noise(&x, &d, dt);
                assert!((q - q.transpose()).amax() < 1e-15);
            }
        }
    }
}
