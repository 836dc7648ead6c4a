//! Position and range-bearing measurement models.

use crate::FilterError;
use nalgebra::{Matrix2, Matrix2x3, Matrix3, SMatrix, SVector, Vector2};
use quarry_core::{
    CoreError, Gaussian, InverseMeasurement, MeasurementModel, Pose2, validate_covariance,
    wrap_angle,
};

fn check_r<const Z: usize>(r: &SMatrix<f64, Z, Z>) -> Result<(), FilterError> {
    validate_covariance(r, "measurement noise R")?;
    Ok(())
}

fn check_sigma(sigma: f64) -> Result<(), FilterError> {
    if sigma.is_finite() && sigma > 0.0 {
        Ok(())
    } else {
        Err(CoreError::invalid("sigma", format!("{sigma} (must be finite and > 0)")).into())
    }
}

/// A direct measurement of the planar position `(x, y)`: the first two components of any
/// position-first state (`[x, y]`, `[x, y, vx, vy]`, `[x, y, vx, vy, ax, ay]`), `H = [I₂ 0]`.
///
/// ```
/// use nalgebra::{Vector2, Vector4};
/// use quarry_core::MeasurementModel;
/// use quarry_filter::Position2;
/// let m = Position2::isotropic(0.5)?;
/// let z: Vector2<f64> = m.predict(&Vector4::new(1.0, 2.0, 3.0, 4.0));
/// assert_eq!(z, Vector2::new(1.0, 2.0));
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Position2 {
    /// Measurement noise covariance `R` (symmetric positive definite).
    pub r: Matrix2<f64>,
}

impl Position2 {
    /// `R = σ² I₂`, σ finite and positive.
    pub fn isotropic(sigma: f64) -> Result<Self, FilterError> {
        check_sigma(sigma)?;
        Ok(Self {
            r: Matrix2::identity() * (sigma * sigma),
        })
    }
    /// A validated `R` (finite, symmetric positive definite).
    pub fn new(r: Matrix2<f64>) -> Result<Self, FilterError> {
        check_r(&r)?;
        Ok(Self { r })
    }
}

/// A direct measurement of the 3-D position `(x, y, z)`: the first three components of a
/// position-first state (spec 001's MEKF state `[x, y, z, ẋ, ẏ]`, `[x, y, z, vx, vy, vz]`),
/// `H = [I₃ 0]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Position3 {
    /// Measurement noise covariance `R` (symmetric positive definite).
    pub r: Matrix3<f64>,
}

impl Position3 {
    /// `R = σ_p² I₃` (spec 001's `R^t`), σ_p finite and positive.
    pub fn isotropic(sigma_p: f64) -> Result<Self, FilterError> {
        check_sigma(sigma_p)?;
        Ok(Self {
            r: Matrix3::identity() * (sigma_p * sigma_p),
        })
    }
    /// A validated `R` (finite, symmetric positive definite).
    pub fn new(r: Matrix3<f64>) -> Result<Self, FilterError> {
        check_r(&r)?;
        Ok(Self { r })
    }
}

macro_rules! position_model {
    ($ty:ty, $z:literal, $($d:literal),+) => {$(
        impl MeasurementModel<$d, $z> for $ty {
            #[inline]
            fn predict(&self, x: &SVector<f64, $d>) -> SVector<f64, $z> {
                x.fixed_rows::<$z>(0).into_owned()
            }
            #[inline]
            fn jacobian(&self, _x: &SVector<f64, $d>) -> SMatrix<f64, $z, $d> {
                SMatrix::<f64, $z, $d>::identity()
            }
            #[inline]
            fn noise(&self, _x: &SVector<f64, $d>) -> SMatrix<f64, $z, $z> {
                self.r
            }
        }
    )+};
}
position_model!(Position2, 2, 2, 4, 6);
position_model!(Position3, 3, 3, 5, 6);

/// Range and bearing `(r, b)` of a point from a sensor at pose `sensor` (spec 000 §2.4):
/// `h(p) = (|p − s|, wrap(atan2(Δy, Δx) − θ))`. State: the point `[p_x, p_y]` (a landmark).
/// The bearing residual wraps to (−π, π].
///
/// ```
/// use nalgebra::Vector2;
/// use quarry_core::{InverseMeasurement, MeasurementModel, Pose2};
/// use quarry_filter::RangeBearing;
/// let m = RangeBearing::new(Pose2::new(1.0, 0.0, 0.0), 0.1, 0.01)?;
/// let z = m.predict(&Vector2::new(1.0, 2.0));
/// assert!((z - Vector2::new(2.0, std::f64::consts::FRAC_PI_2)).norm() < 1e-12);
/// let lm = m.initialise(&z)?;                  // landmark initialisation
/// assert!((lm.mean - Vector2::new(1.0, 2.0)).norm() < 1e-12);
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeBearing {
    /// The sensor pose in the state's frame.
    pub sensor: Pose2,
    /// Measurement noise covariance `R` of `(range, bearing)`.
    pub r: Matrix2<f64>,
}

impl RangeBearing {
    /// `R = diag(σ_r², σ_b²)`, both finite and positive.
    pub fn new(sensor: Pose2, sigma_range: f64, sigma_bearing: f64) -> Result<Self, FilterError> {
        check_sigma(sigma_range)?;
        check_sigma(sigma_bearing)?;
        Self::with_cov(
            sensor,
            Matrix2::new(
                sigma_range * sigma_range,
                0.0,
                0.0,
                sigma_bearing * sigma_bearing,
            ),
        )
    }

    /// A validated full `R` and a finite sensor pose.
    pub fn with_cov(sensor: Pose2, r: Matrix2<f64>) -> Result<Self, FilterError> {
        if !sensor.is_finite() {
            return Err(CoreError::NonFinite {
                what: "sensor pose",
            }
            .into());
        }
        check_r(&r)?;
        Ok(Self { sensor, r })
    }

    #[inline]
    fn h(&self, px: f64, py: f64) -> Vector2<f64> {
        let dx = px - self.sensor.x;
        let dy = py - self.sensor.y;
        // √(Δx² + Δy²) where the square is a normal number (every realistic geometry), `hypot`
        // (four times the cost) where it would under- or overflow.
        let q = dx * dx + dy * dy;
        let range = if q.is_normal() {
            q.sqrt()
        } else {
            dx.hypot(dy)
        };
        Vector2::new(range, wrap_angle(dy.atan2(dx) - self.sensor.theta))
    }

    #[inline]
    fn h_p(&self, px: f64, py: f64) -> Matrix2<f64> {
        let dx = px - self.sensor.x;
        let dy = py - self.sensor.y;
        let q = dx * dx + dy * dy;
        // One division: 1/r, then 1/q = (1/r)².
        let inv_r = 1.0 / q.sqrt();
        let inv_q = inv_r * inv_r;
        Matrix2::new(dx * inv_r, dy * inv_r, -dy * inv_q, dx * inv_q)
    }

    /// `H_x = ∂h/∂(sensor pose)` at point `p` (spec 000 §2.4; needed by a FastSLAM 2.0 proposal).
    pub fn pose_jacobian(&self, p: &Vector2<f64>) -> Matrix2x3<f64> {
        let dx = p.x - self.sensor.x;
        let dy = p.y - self.sensor.y;
        let q = dx * dx + dy * dy;
        let r = q.sqrt();
        Matrix2x3::new(-dx / r, -dy / r, 0.0, dy / q, -dx / q, -1.0)
    }

    /// The point and `G_z = ∂p/∂z` implied by `z` (checked: finite, range > 0).
    fn inverse(&self, z: &Vector2<f64>) -> Result<(Vector2<f64>, Matrix2<f64>), FilterError> {
        if !z.iter().all(|v| v.is_finite()) {
            return Err(FilterError::NonFiniteMeasurement);
        }
        if z[0] <= 0.0 {
            return Err(CoreError::invalid(
                "range",
                format!("{} (must be > 0 to initialise)", z[0]),
            )
            .into());
        }
        let (s, c) = (self.sensor.theta + z[1]).sin_cos();
        let p = Vector2::new(self.sensor.x + z[0] * c, self.sensor.y + z[0] * s);
        let g = Matrix2::new(c, -z[0] * s, s, z[0] * c);
        Ok((p, g))
    }
}

#[inline]
fn wrap_bearing(z: &Vector2<f64>, zhat: &Vector2<f64>) -> Vector2<f64> {
    Vector2::new(z[0] - zhat[0], wrap_angle(z[1] - zhat[1]))
}

impl MeasurementModel<2, 2> for RangeBearing {
    #[inline]
    fn predict(&self, x: &Vector2<f64>) -> Vector2<f64> {
        self.h(x[0], x[1])
    }
    #[inline]
    fn jacobian(&self, x: &Vector2<f64>) -> Matrix2<f64> {
        self.h_p(x[0], x[1])
    }
    #[inline]
    fn noise(&self, _x: &Vector2<f64>) -> Matrix2<f64> {
        self.r
    }
    #[inline]
    fn residual(&self, z: &Vector2<f64>, zhat: &Vector2<f64>) -> Vector2<f64> {
        wrap_bearing(z, zhat)
    }
}

impl InverseMeasurement<2, 2> for RangeBearing {
    /// `m = s + r (cos(θ + b), sin(θ + b))`, `Σ = G_z R G_zᵀ` (spec 000 §2.5).
    fn initialise(&self, z: &Vector2<f64>) -> Result<Gaussian<2>, CoreError> {
        let (p, g) = self.inverse(z)?;
        Gaussian::try_new(p, g * self.r * g.transpose())
    }
}

/// Range and bearing of the position of a constant-velocity state `[x, y, vx, vy]` from a sensor
/// at pose `sensor`: `H = [H_p 0₂ₓ₂]` (spec 000 §2.7). The bearing residual wraps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeBearingCv {
    /// The point model it wraps (sensor pose and `R`).
    pub point: RangeBearing,
}

impl RangeBearingCv {
    /// `R = diag(σ_r², σ_b²)`, both finite and positive.
    pub fn new(sensor: Pose2, sigma_range: f64, sigma_bearing: f64) -> Result<Self, FilterError> {
        Ok(Self {
            point: RangeBearing::new(sensor, sigma_range, sigma_bearing)?,
        })
    }

    /// A target initialised from one detection (spec 000 §2.12): position from the inverse model
    /// with covariance `G_z R G_zᵀ`, velocity 0 with standard deviation `sigma_v0` per axis.
    pub fn initialise_with_velocity(
        &self,
        z: &Vector2<f64>,
        sigma_v0: f64,
    ) -> Result<Gaussian<4>, FilterError> {
        check_sigma(sigma_v0)?;
        let (p, g) = self.point.inverse(z)?;
        let pc = g * self.point.r * g.transpose();
        let mut cov = SMatrix::<f64, 4, 4>::zeros();
        cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&pc);
        cov[(2, 2)] = sigma_v0 * sigma_v0;
        cov[(3, 3)] = sigma_v0 * sigma_v0;
        Ok(Gaussian::try_new(
            SVector::<f64, 4>::new(p.x, p.y, 0.0, 0.0),
            cov,
        )?)
    }
}

impl MeasurementModel<4, 2> for RangeBearingCv {
    #[inline]
    fn predict(&self, x: &SVector<f64, 4>) -> Vector2<f64> {
        self.point.h(x[0], x[1])
    }
    #[inline]
    fn jacobian(&self, x: &SVector<f64, 4>) -> SMatrix<f64, 2, 4> {
        let hp = self.point.h_p(x[0], x[1]);
        let mut h = SMatrix::<f64, 2, 4>::zeros();
        h.fixed_view_mut::<2, 2>(0, 0).copy_from(&hp);
        h
    }
    #[inline]
    fn noise(&self, _x: &SVector<f64, 4>) -> Matrix2<f64> {
        self.point.r
    }
    #[inline]
    fn residual(&self, z: &Vector2<f64>, zhat: &Vector2<f64>) -> Vector2<f64> {
        wrap_bearing(z, zhat)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    #[test]
    fn residual_wraps() {
        let m = RangeBearing::new(Pose2::identity(), 0.1, 0.01).unwrap();
        let nu = m.residual(
            &Vector2::new(10.0, PI - 0.01),
            &Vector2::new(10.0, -PI + 0.01),
        );
        assert!((nu[1] + 0.02).abs() < 1e-12);
        assert!(RangeBearing::new(Pose2::identity(), 0.0, 0.01).is_err());
        assert!(m.initialise(&Vector2::new(f64::NAN, 0.0)).is_err());
        assert!(m.initialise(&Vector2::new(0.0, 0.0)).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn range_bearing_jacobians_and_inverse(
            sx in -5.0..5.0f64, sy in -5.0..5.0f64, st in -PI..PI,
            range in 0.5..50.0f64, bearing in -PI..PI,
        ) {
            let m = RangeBearing::new(Pose2::new(sx, sy, st), 0.3, 0.02).unwrap();
            let (s, c) = (st + bearing).sin_cos();
            let p = Vector2::new(sx + range * c, sy + range * s);
            // H_p against central differences, bearing difference wrapped
            let h = 1e-6;
            let j = m.jacobian(&p);
            for k in 0..2 {
                let mut a = p; let mut b = p;
                a[k] += h; b[k] -= h;
                let d = m.residual(&m.predict(&a), &m.predict(&b)) / (2.0 * h);
                for i in 0..2 {
                    prop_assert!((j[(i, k)] - d[i]).abs() <= 1e-6 * j[(i, k)].abs().max(1.0));
                }
            }
            // H_x against central differences in the sensor pose
            let jx = m.pose_jacobian(&p);
            for k in 0..3 {
                let mut a = m; let mut b = m;
                match k { 0 => { a.sensor.x += h; b.sensor.x -= h; }
                          1 => { a.sensor.y += h; b.sensor.y -= h; }
                          _ => { a.sensor.theta += h; b.sensor.theta -= h; } }
                let d = m.residual(&a.predict(&p), &b.predict(&p)) / (2.0 * h);
                for i in 0..2 {
                    prop_assert!((jx[(i, k)] - d[i]).abs() <= 1e-6 * jx[(i, k)].abs().max(1.0));
                }
            }
            // inverse round trip
            let z = m.predict(&p);
            let g = m.initialise(&z).unwrap();
            let z2 = m.predict(&g.mean);
            prop_assert!((z2[0] - z[0]).abs() < 1e-9 && wrap_angle(z2[1] - z[1]).abs() < 1e-9);
            let nu = m.residual(&z, &Vector2::new(z[0], z[1] + 3.0));
            prop_assert!(nu[1] > -PI && nu[1] <= PI);
        }
    }
}
