//! Validation gates, all in quarry-core's normalised convention: a measurement is accepted iff
//! [`Gate::distance2`] `<= 1`.
//!
//! - [`ChiSquareGate`]: the ellipsoidal innovation gate `νᵀS⁻¹ν ≤ γ`, `γ = χ²_Z⁻¹(P_G)` for the
//!   measurement dimension `Z` (any `Z`; quantiles from [`crate::chi2::chi2_quantile`]).
//! - [`RectGate`]: the bounding box of that ellipse, `|ν_k| ≤ √(γ S_kk)` — a cheap pre-gate that
//!   never rejects a measurement the ellipsoidal gate accepts (no inverse needed).
//! - [`PositionVelocityGate`]: spec 003 eq. (8) on positions and finite-difference velocities.

use crate::chi2::chi2_quantile;
use crate::error::check_prob;
use nalgebra::{SVector, Vector2};
use quarry_core::{CoreError, Gate, Gaussian};

/// Dimensions whose thresholds are precomputed by [`ChiSquareGate::new`].
const PRECOMPUTED: usize = 8;

/// Ellipsoidal chi-square gate on the innovation.
///
/// The track is the predicted measurement `N(ẑ, S)` (a [`Gaussian<Z>`]); the measurement is a
/// `SVector<f64, Z>`. `distance2 = (z − ẑ)ᵀ S⁻¹ (z − ẑ) / γ_Z`, with `γ_Z` the `prob_gate`
/// quantile of χ²_Z. An `S` that is not positive definite gives `+inf` (outside).
///
/// ```
/// use nalgebra::{Matrix2, Vector2};
/// use quarry_assoc::ChiSquareGate;
/// use quarry_core::{Gate, Gaussian};
/// let gate = ChiSquareGate::new(0.99)?;
/// assert!((gate.threshold(2)? - 9.2103).abs() < 1e-4);
/// let pred = Gaussian::try_new(Vector2::zeros(), Matrix2::identity())?;
/// assert!(gate.accepts(&pred, &Vector2::new(3.0, 0.0), 0.0)); // d² = 9 < 9.21
/// assert!(!gate.accepts(&pred, &Vector2::new(3.1, 0.0), 0.0));
/// # Ok::<(), quarry_core::CoreError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ChiSquareGate {
    prob_gate: f64,
    thresholds: [f64; PRECOMPUTED],
}

impl ChiSquareGate {
    /// A gate that accepts a correct measurement with probability `prob_gate` ∈ (0, 1).
    pub fn new(prob_gate: f64) -> Result<Self, CoreError> {
        if !(prob_gate.is_finite() && prob_gate > 0.0 && prob_gate < 1.0) {
            return Err(CoreError::invalid(
                "prob_gate",
                format!("{prob_gate} must lie in the open interval (0, 1)"),
            ));
        }
        let mut thresholds = [0.0; PRECOMPUTED];
        for (k, t) in thresholds.iter_mut().enumerate() {
            *t = chi2_quantile(k as u32 + 1, prob_gate)?;
        }
        Ok(Self {
            prob_gate,
            thresholds,
        })
    }

    /// The gate probability P_G.
    pub fn prob_gate(&self) -> f64 {
        self.prob_gate
    }

    /// The threshold γ on the squared Mahalanobis distance for measurements of dimension `dim`.
    pub fn threshold(&self, dim: usize) -> Result<f64, CoreError> {
        match dim {
            0 => Err(CoreError::invalid("dim", "must be at least 1")),
            d if d <= PRECOMPUTED => Ok(self.thresholds[d - 1]),
            d => chi2_quantile(d as u32, self.prob_gate),
        }
    }

    fn gamma(&self, dim: usize) -> f64 {
        self.threshold(dim).unwrap_or(f64::NAN)
    }

    /// The squared Mahalanobis distance `d²` (not normalised), or `+inf` when `S` is not
    /// positive definite or the innovation is not finite.
    pub fn mahalanobis2<const Z: usize>(pred: &Gaussian<Z>, z: &SVector<f64, Z>) -> f64 {
        match pred.mahalanobis2(z) {
            Ok(d) if d.is_finite() => d,
            _ => f64::INFINITY,
        }
    }

    /// The rectangular pre-gate circumscribing this gate in dimension `dim`.
    pub fn rect(&self, dim: usize) -> Result<RectGate, CoreError> {
        RectGate::new(self.threshold(dim)?)
    }
}

impl<const Z: usize> Gate<Gaussian<Z>, SVector<f64, Z>> for ChiSquareGate {
    fn distance2(&self, track: &Gaussian<Z>, z: &SVector<f64, Z>, _dt: f64) -> f64 {
        Self::mahalanobis2(track, z) / self.gamma(Z)
    }
}

/// Rectangular (axis-aligned box) gate: `distance2 = max_k ν_k² / (γ S_kk)`.
///
/// With the same γ it circumscribes the ellipsoidal gate (`ν_k² ≤ γ S_kk` holds for every `ν`
/// with `νᵀS⁻¹ν ≤ γ`), so it is a safe, inverse-free pre-filter.
///
/// ```
/// use nalgebra::{Matrix2, Vector2};
/// use quarry_assoc::RectGate;
/// use quarry_core::{Gate, Gaussian};
/// let g = RectGate::new(9.0)?;
/// let pred = Gaussian::try_new(Vector2::zeros(), Matrix2::identity())?;
/// assert!(g.accepts(&pred, &Vector2::new(2.9, 2.9), 0.0)); // a corner the ellipse rejects
/// # Ok::<(), quarry_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectGate {
    gamma: f64,
}

impl RectGate {
    /// A box gate `|ν_k| ≤ √(γ S_kk)` for a positive finite γ.
    pub fn new(gamma: f64) -> Result<Self, CoreError> {
        if !(gamma.is_finite() && gamma > 0.0) {
            return Err(CoreError::invalid(
                "gamma",
                format!("{gamma} must be > 0 and finite"),
            ));
        }
        Ok(Self { gamma })
    }

    /// The threshold γ.
    pub fn gamma(&self) -> f64 {
        self.gamma
    }
}

impl<const Z: usize> Gate<Gaussian<Z>, SVector<f64, Z>> for RectGate {
    fn distance2(&self, track: &Gaussian<Z>, z: &SVector<f64, Z>, _dt: f64) -> f64 {
        let mut worst = 0.0_f64;
        for k in 0..Z {
            let nu = z[k] - track.mean[k];
            let s = track.cov[(k, k)];
            let d = if s > 0.0 {
                nu * nu / (self.gamma * s)
            } else {
                f64::INFINITY
            };
            if d.is_nan() {
                return f64::INFINITY;
            }
            worst = worst.max(d);
        }
        worst
    }
}

/// A track as the position–velocity gate sees it (spec 003 §2.7): its last position and its
/// finite-difference velocity, `None` while unknown (a track created at its previous update).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PvState {
    /// Position (m).
    pub pos: Vector2<f64>,
    /// Velocity (m/s), `None` when unknown.
    pub vel: Option<Vector2<f64>>,
}

/// The position–velocity gate of spec 003 eq. (8):
///
/// `G = ΔX²/(k²σ_X²) + ΔY²/(k²σ_Y²) + ΔẊ²/(k²σ_Ẋ²) + ΔẎ²/(k²σ_Ẏ²) ≤ 1`
///
/// with four separate σ (the spec's resolution of the paper's symbol reuse), the velocity terms
/// dropped when the previous velocity is unknown, and σ_X, σ_Y scaled by `Δt/T_F` when
/// `Δt > T_F` (missed frames). As a [`Gate`], the track is a [`PvState`], the measurement the new
/// position, and `dt` the time since the track's last update; the new velocity is the finite
/// difference `(z − pos)/dt`.
///
/// ```
/// use nalgebra::Vector2;
/// use quarry_assoc::{PositionVelocityGate, PvState};
/// use quarry_core::Gate;
/// let g = PositionVelocityGate::spec003();
/// let t = PvState { pos: Vector2::new(1.0, 1.0), vel: None };
/// assert!(g.accepts(&t, &Vector2::new(1.1, 1.0), 0.05));  // 0.1 m < kσ = 0.22 m
/// assert!(!g.accepts(&t, &Vector2::new(1.3, 1.0), 0.05));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionVelocityGate {
    /// σ_X, σ_Y (m).
    pub sigma_pos: [f64; 2],
    /// σ_Ẋ, σ_Ẏ (m/s).
    pub sigma_vel: [f64; 2],
    /// Gate constant k (`√χ²₄(0.99) = 3.644` in spec 003).
    pub k: f64,
    /// Nominal frame period T_F (s): σ_pos is scaled by `Δt/T_F` when `Δt > T_F`.
    pub frame_period: f64,
}

impl PositionVelocityGate {
    /// Spec 003's values: σ_X = σ_Y = 0.06 m, σ_Ẋ = σ_Ẏ = 1.5 m/s, k = √χ²₄(0.99), T_F = 50 ms.
    pub fn spec003() -> Self {
        Self {
            sigma_pos: [0.06, 0.06],
            sigma_vel: [1.5, 1.5],
            k: chi2_quantile(4, 0.99).map_or(3.643_721, f64::sqrt),
            frame_period: 0.05,
        }
    }

    /// Checks every parameter is positive and finite.
    pub fn validate(&self) -> Result<(), CoreError> {
        let all = [
            self.sigma_pos[0],
            self.sigma_pos[1],
            self.sigma_vel[0],
            self.sigma_vel[1],
            self.k,
            self.frame_period,
        ];
        if all.iter().all(|v| v.is_finite() && *v > 0.0) {
            Ok(())
        } else {
            Err(CoreError::invalid(
                "PositionVelocityGate",
                "sigmas, k and frame_period must be positive and finite",
            ))
        }
    }

    /// Eq. (8) between two states `dt` seconds apart (velocity terms only when both velocities
    /// are known). Symmetric in its two state arguments.
    pub fn eq8(&self, prev: &PvState, cur: &PvState, dt: f64) -> f64 {
        let scale = if dt.is_finite() && dt > self.frame_period {
            dt / self.frame_period
        } else {
            1.0
        };
        let k2 = self.k * self.k;
        let d = cur.pos - prev.pos;
        let sx = self.sigma_pos[0] * scale;
        let sy = self.sigma_pos[1] * scale;
        let mut g = d.x * d.x / (k2 * sx * sx) + d.y * d.y / (k2 * sy * sy);
        if let (Some(v0), Some(v1)) = (prev.vel, cur.vel) {
            let dv = v1 - v0;
            g += dv.x * dv.x / (k2 * self.sigma_vel[0] * self.sigma_vel[0])
                + dv.y * dv.y / (k2 * self.sigma_vel[1] * self.sigma_vel[1]);
        }
        if g.is_nan() { f64::INFINITY } else { g }
    }
}

impl Gate<PvState, Vector2<f64>> for PositionVelocityGate {
    fn distance2(&self, track: &PvState, z: &Vector2<f64>, dt: f64) -> f64 {
        let vel = if dt.is_finite() && dt > 0.0 {
            Some((z - track.pos) / dt)
        } else {
            None
        };
        let cur = PvState { pos: *z, vel };
        self.eq8(track, &cur, dt)
    }
}

/// Checks a gate probability (exposed for the associators).
pub(crate) fn check_prob_gate(p: f64) -> Result<(), CoreError> {
    check_prob("prob_gate", p, true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix3, Vector3};
    use proptest::prelude::*;

    #[test]
    fn thresholds() {
        let g = ChiSquareGate::new(0.99).unwrap();
        assert!((g.threshold(2).unwrap() - 9.2103).abs() < 1e-4);
        assert!((g.threshold(4).unwrap() - 13.2767).abs() < 1e-4);
        let g = ChiSquareGate::new(0.999).unwrap();
        assert!((g.threshold(3).unwrap() - 16.2662).abs() < 1e-4);
        assert!((g.threshold(12).unwrap() - 32.9095).abs() < 1e-4);
        assert!(ChiSquareGate::new(1.0).is_err());
        assert!(ChiSquareGate::new(f64::NAN).is_err());
    }

    #[test]
    fn nan_measurement_is_outside() {
        let g = ChiSquareGate::new(0.99).unwrap();
        let pred = Gaussian::try_new(Vector2::zeros(), Matrix2::identity()).unwrap();
        assert!(!g.accepts(&pred, &Vector2::new(f64::NAN, 0.0), 0.0));
        assert!(
            !RectGate::new(9.0)
                .unwrap()
                .accepts(&pred, &Vector2::new(f64::NAN, 0.0), 0.0)
        );
    }

    #[test]
    fn pv_gate_matches_mahalanobis() {
        let g = PositionVelocityGate::spec003();
        let a = PvState {
            pos: Vector2::new(0.0, 0.0),
            vel: Some(Vector2::new(1.0, 0.0)),
        };
        let b = PvState {
            pos: Vector2::new(0.05, 0.02),
            vel: Some(Vector2::new(1.5, -0.5)),
        };
        let d = 0.05f64.powi(2) / 0.06f64.powi(2)
            + 0.02f64.powi(2) / 0.06f64.powi(2)
            + 0.25 / 2.25
            + 0.25 / 2.25;
        assert!((g.eq8(&a, &b, 0.05) - d / (g.k * g.k)).abs() < 1e-12);
        assert!((g.eq8(&a, &b, 0.05) - g.eq8(&b, &a, 0.05)).abs() < 1e-15);
        assert_eq!(g.eq8(&a, &a, 0.05), 0.0);
        // Missed frames widen the position part.
        assert!(g.eq8(&a, &b, 0.1) < g.eq8(&a, &b, 0.05));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn rect_contains_ellipse(a in 0.1f64..3.0, b in 0.1f64..3.0, c in -0.9f64..0.9,
                                 x in -6.0f64..6.0, y in -6.0f64..6.0, z in -6.0f64..6.0) {
            let l = Matrix3::new(a, 0.0, 0.0, c, b, 0.0, 0.3, -c, 1.0);
            let s = l * l.transpose();
            let pred = Gaussian::try_new(Vector3::zeros(), s).unwrap();
            let gate = ChiSquareGate::new(0.99).unwrap();
            let rect = gate.rect(3).unwrap();
            let zv = Vector3::new(x, y, z);
            if gate.accepts(&pred, &zv, 0.0) {
                prop_assert!(rect.accepts(&pred, &zv, 0.0));
            }
        }

        #[test]
        fn pv_gate_symmetric_and_scaling(ax in -5.0f64..5.0, ay in -5.0f64..5.0, bx in -5.0f64..5.0,
                                         by in -5.0f64..5.0, va in -3.0f64..3.0, vb in -3.0f64..3.0,
                                         k in 1.0f64..5.0, dt in 0.01f64..0.2) {
            // Spec 003 §8 test 9: G(a, b) = G(b, a), G ≥ 0, G(a, a) = 0, G ∝ 1/k², and G equals
            // the Mahalanobis distance under diag(σ²) divided by k².
            let g = PositionVelocityGate { k, ..PositionVelocityGate::spec003() };
            let a = PvState { pos: Vector2::new(ax, ay), vel: Some(Vector2::new(va, vb)) };
            let b = PvState { pos: Vector2::new(bx, by), vel: Some(Vector2::new(vb, va)) };
            let gab = g.eq8(&a, &b, dt);
            prop_assert!(gab >= 0.0);
            prop_assert!((gab - g.eq8(&b, &a, dt)).abs() <= 1e-12 * gab.max(1.0));
            prop_assert_eq!(g.eq8(&a, &a, dt), 0.0);
            let g2 = PositionVelocityGate { k: 2.0 * k, ..g };
            prop_assert!((g2.eq8(&a, &b, dt) - gab / 4.0).abs() <= 1e-12 * gab.max(1.0));
            let scale = if dt > g.frame_period { dt / g.frame_period } else { 1.0 };
            let sp = g.sigma_pos[0] * scale;
            let maha = ((bx - ax) / sp).powi(2) + ((by - ay) / sp).powi(2)
                + ((va - vb) / 1.5).powi(2) + ((vb - va) / 1.5).powi(2);
            prop_assert!((gab - maha / (k * k)).abs() <= 1e-9 * gab.max(1.0));
        }
    }
}
