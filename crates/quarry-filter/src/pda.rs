//! The PDA combined-innovation update (spec 000 §2.9; Bar-Shalom & Fortmann 1988).
//!
//! Given association probabilities `β_0` (missed detection) and `β_j` (detection `j`), every EKF
//! update linearised at the same prior shares `S` and `K`, so the β-weighted mixture of updates
//! collapses by moment matching to
//!
//! ```text
//! ν̄ = Σ_j β_j ν_j,    x = x⁻ + K ν̄
//! P = β_0 P⁻ + (1 − β_0) P_c + K (Σ_j β_j ν_j ν_jᵀ − ν̄ ν̄ᵀ) Kᵀ,    P ← ½ (P + Pᵀ)
//! ```
//!
//! with `P_c` the Joseph-form single-update covariance. The spread term is positive
//! semi-definite, so `P` stays positive definite.
//!
//! ```
//! use nalgebra::{Matrix4, Vector2, Vector4};
//! use quarry_core::Gaussian;
//! use quarry_filter::{pda, Position2};
//! let prior = Gaussian::try_new(Vector4::zeros(), Matrix4::identity())?;
//! let zs = [Vector2::new(1.0, 0.0), Vector2::new(-1.0, 0.0)];
//! let post = pda::update_with_model(&prior, &Position2::isotropic(1.0)?, &zs, &[0.2, 0.4, 0.4])?;
//! assert!(post.mean.norm() < 1e-12);                 // symmetric detections cancel
//! assert!(post.cov[(0, 0)] > post.cov[(1, 1)]);      // but they spread the x variance
//! # Ok::<(), quarry_filter::FilterError>(())
//! ```

use crate::FilterError;
use crate::ekf::{MeasurementPrediction, UpdateForm};
use nalgebra::{SMatrix, SVector};
use quarry_core::{CoreError, Gaussian, MeasurementModel};

/// Tolerance on `Σ β = 1`.
pub const BETA_SUM_TOL: f64 = 1e-9;

/// The PDA update of `prior` from innovations `innovations` (`ν_j = z_j ⊖ ẑ`, computed with
/// [`MeasurementPrediction::innovation`]) and the association row `beta_row` =
/// `[β_0, β_1, .., β_n]` (column 0 = missed; `n = innovations.len()`).
///
/// Errors: a `beta_row` of the wrong length, with entries outside `[0, 1]` or not summing to 1
/// (within [`BETA_SUM_TOL`]), a non-finite innovation, or a non-finite result.
pub fn update<const D: usize, const Z: usize>(
    prior: &Gaussian<D>,
    pred: &MeasurementPrediction<D, Z>,
    innovations: &[SVector<f64, Z>],
    beta_row: &[f64],
) -> Result<Gaussian<D>, FilterError> {
    quarry_core::ensure_len(beta_row.len(), innovations.len() + 1, "PDA beta row")?;
    if beta_row
        .iter()
        .any(|b| !(b.is_finite() && (0.0..=1.0 + BETA_SUM_TOL).contains(b)))
    {
        return Err(CoreError::invalid("beta_row", "entries must be finite and in [0, 1]").into());
    }
    let sum: f64 = beta_row.iter().sum();
    if (sum - 1.0).abs() > BETA_SUM_TOL {
        return Err(
            CoreError::invalid("beta_row", format!("must sum to 1 (sums to {sum})")).into(),
        );
    }
    if innovations
        .iter()
        .any(|nu| !nu.iter().all(|v| v.is_finite()))
    {
        return Err(FilterError::NonFiniteMeasurement);
    }
    let b0 = beta_row[0];
    let mut nu_bar = SVector::<f64, Z>::zeros();
    let mut spread = SMatrix::<f64, Z, Z>::zeros();
    for (nu, &b) in innovations.iter().zip(&beta_row[1..]) {
        nu_bar += nu * b;
        spread += nu * nu.transpose() * b;
    }
    spread -= nu_bar * nu_bar.transpose();
    let k = &pred.gain;
    let pc = pred.posterior_cov(&prior.cov, UpdateForm::Joseph);
    let p = prior.cov * b0 + pc * (1.0 - b0) + k * spread * k.transpose();
    let out = Gaussian::new_unchecked(prior.mean + k * nu_bar, (p + p.transpose()) * 0.5);
    if out.mean.iter().chain(out.cov.iter()).all(|v| v.is_finite()) {
        Ok(out)
    } else {
        Err(FilterError::NonFiniteResult { what: "PDA update" })
    }
}

/// [`update`] from raw measurements: linearises `model` at the prior, computes the innovations
/// (bearing residuals wrapped by the model) and applies the PDA update.
pub fn update_with_model<const D: usize, const Z: usize, H>(
    prior: &Gaussian<D>,
    model: &H,
    zs: &[SVector<f64, Z>],
    beta_row: &[f64],
) -> Result<Gaussian<D>, FilterError>
where
    H: MeasurementModel<D, Z> + ?Sized,
{
    let pred = MeasurementPrediction::new(prior, model)?;
    let nus = zs
        .iter()
        .map(|z| pred.innovation(model, z))
        .collect::<Result<Vec<_>, _>>()?;
    update(prior, &pred, &nus, beta_row)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Position2, RangeBearingCv, ekf};
    use nalgebra::{Matrix4, Vector2, Vector4};
    use proptest::prelude::*;
    use quarry_core::Pose2;

    fn prior() -> Gaussian<4> {
        let a = Matrix4::new(
            1.0, 0.2, 0.0, 0.1, 0.0, 0.8, 0.3, 0.0, 0.1, 0.0, 0.5, 0.2, 0.0, 0.1, 0.0, 0.4,
        );
        Gaussian::try_new(
            Vector4::new(12.0, 5.0, -1.0, 0.5),
            a * a.transpose() + Matrix4::identity() * 0.1,
        )
        .unwrap()
    }

    #[test]
    fn limits() {
        let g = prior();
        let m = RangeBearingCv::new(Pose2::new(0.5, 0.0, 0.2), 0.3, 0.03).unwrap();
        let zs = [Vector2::new(12.5, 0.2), Vector2::new(13.0, 0.3)];
        let missed = update_with_model(&g, &m, &zs, &[1.0, 0.0, 0.0]).unwrap();
        assert!((missed.mean - g.mean).amax() < 1e-15 && (missed.cov - g.cov).amax() < 1e-15);
        let one = update_with_model(&g, &m, &zs[..1], &[0.0, 1.0]).unwrap();
        let (ekf_post, _) = ekf::update(&g, &m, &zs[0], UpdateForm::Joseph).unwrap();
        assert!((one.mean - ekf_post.mean).amax() < 1e-12);
        assert!((one.cov - ekf_post.cov).amax() < 1e-12);
        assert!(update_with_model(&g, &m, &zs, &[0.5, 0.5]).is_err());
        assert!(update_with_model(&g, &m, &zs, &[0.5, 0.5, 0.5]).is_err());
        assert!(update_with_model(&g, &m, &zs, &[-0.5, 1.0, 0.5]).is_err());
        assert!(update_with_model(&g, &m, &zs, &[f64::NAN, 1.0, 0.0]).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Spec 000 §6.1 test 8: the collapsed moments equal the brute-force mixture moments of
        /// the prior component and every EKF component, and stay SPD.
        #[test]
        fn equals_brute_force_mixture(
            raw in proptest::collection::vec(0.01..1.0f64, 1..6),
            offsets in proptest::collection::vec((-2.0..2.0f64, -2.0..2.0f64), 5),
        ) {
            let g = prior();
            let m = Position2::isotropic(0.7).unwrap();
            let n = raw.len() - 1;
            let total: f64 = raw.iter().sum();
            let beta: Vec<f64> = raw.iter().map(|v| v / total).collect();
            let zs: Vec<_> = offsets[..n].iter().map(|&(a, b)| Vector2::new(g.mean[0] + a, g.mean[1] + b)).collect();
            let post = update_with_model(&g, &m, &zs, &beta).unwrap();
            // brute force
            let mut comps = vec![(beta[0], g)];
            for (z, &b) in zs.iter().zip(&beta[1..]) {
                comps.push((b, ekf::update(&g, &m, z, UpdateForm::Joseph).unwrap().0));
            }
            let mean: Vector4<f64> = comps.iter().map(|(b, c)| c.mean * *b).sum();
            let mut cov = Matrix4::zeros();
            for (b, c) in &comps {
                let d = c.mean - mean;
                cov += (c.cov + d * d.transpose()) * *b;
            }
            prop_assert!((post.mean - mean).amax() < 1e-9);
            prop_assert!((post.cov - cov).amax() < 1e-9);
            prop_assert!(post.cholesky().is_ok());
            prop_assert!((post.cov - post.cov.transpose()).amax() <= 1e-12 * post.cov.amax());
        }
    }
}
