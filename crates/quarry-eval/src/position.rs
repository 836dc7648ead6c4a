//! Position-error series: RMSE, NEES and the chi-square consistency test of a filter.
//!
//! ```
//! use nalgebra::{Matrix2, Vector2};
//! use quarry_eval::position::{nees, nees_consistency, position_rmse};
//!
//! let truth = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
//! let est = [[0.3, 0.4], [1.0, 0.0], [2.0, 0.0]];
//! let rmse = position_rmse(&est, &truth)?;
//! assert!((rmse - (0.25f64 / 3.0).sqrt()).abs() < 1e-12);
//!
//! let e = [Vector2::new(0.1, -0.2), Vector2::new(-0.3, 0.1)];
//! let p = [Matrix2::identity() * 0.04, Matrix2::identity() * 0.04];
//! let q = nees(&e, &p)?;
//! assert!((q[0] - 1.25).abs() < 1e-12);
//! let check = nees_consistency(&q, 2, 0.95)?;
//! assert!(check.lower < check.mean && check.mean < check.upper && check.consistent);
//! # Ok::<(), quarry_eval::EvalError>(())
//! ```

use nalgebra::{SMatrix, SVector};
use quarry_core::CoreError;

use crate::EvalError;

/// Root mean square of scalar errors (e.g. position error norms), `sqrt(mean(e^2))`.
pub fn rmse(errors: &[f64]) -> Result<f64, EvalError> {
    if errors.is_empty() {
        return Err(CoreError::Empty {
            what: "error series",
        }
        .into());
    }
    quarry_core::ensure_finite(errors, "error series")?;
    Ok((errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt())
}

/// Correlation time of an error series (spec 000 §4.3 E5): the smallest lag τ ≥ 1 at which the
/// normalised autocorrelation ρ(τ) = Σ_k (e_k − ē)(e_{k+τ} − ē) / Σ_k (e_k − ē)² drops below
/// 1/e, times the sample period `dt` (s). `Ok(None)` when it never does within the series, or
/// when the series is constant (ρ undefined).
///
/// ```
/// use quarry_eval::position::correlation_time;
/// // alternating signs: ρ(1) = -(n-1)/n < 1/e, so τ = one sample
/// let e = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0];
/// assert_eq!(correlation_time(&e, 0.2)?, Some(0.2));
/// # Ok::<(), quarry_eval::EvalError>(())
/// ```
pub fn correlation_time(errors: &[f64], dt: f64) -> Result<Option<f64>, EvalError> {
    if errors.len() < 2 {
        return Err(CoreError::Empty {
            what: "error series (needs at least 2 samples)",
        }
        .into());
    }
    quarry_core::ensure_finite(errors, "error series")?;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(CoreError::invalid("dt", format!("{dt} (must be finite and > 0)")).into());
    }
    let n = errors.len();
    let m = errors.iter().sum::<f64>() / n as f64;
    let d: Vec<f64> = errors.iter().map(|e| e - m).collect();
    let c0: f64 = d.iter().map(|v| v * v).sum();
    if c0 <= f64::EPSILON * m.abs().max(1.0) * n as f64 * f64::EPSILON {
        return Ok(None);
    }
    let thr = (-1.0f64).exp();
    for tau in 1..n {
        let c: f64 = d[..n - tau].iter().zip(&d[tau..]).map(|(a, b)| a * b).sum();
        if c / c0 < thr {
            return Ok(Some(tau as f64 * dt));
        }
    }
    Ok(None)
}

/// Euclidean error of each estimate against the truth of the same index.
pub fn position_errors<const N: usize>(
    estimates: &[[f64; N]],
    truth: &[[f64; N]],
) -> Result<Vec<f64>, EvalError> {
    quarry_core::ensure_len(estimates.len(), truth.len(), "estimates vs truth")?;
    if estimates.is_empty() {
        return Err(CoreError::Empty { what: "estimates" }.into());
    }
    quarry_core::ensure_finite(estimates.iter().flatten(), "estimates")?;
    quarry_core::ensure_finite(truth.iter().flatten(), "truth")?;
    Ok(estimates
        .iter()
        .zip(truth)
        .map(|(e, t)| {
            e.iter()
                .zip(t)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt()
        })
        .collect())
}

/// Position RMSE `sqrt(mean |est - truth|^2)`.
pub fn position_rmse<const N: usize>(
    estimates: &[[f64; N]],
    truth: &[[f64; N]],
) -> Result<f64, EvalError> {
    rmse(&position_errors(estimates, truth)?)
}

/// Normalised estimation error squared `e^T P^-1 e` of each (error, covariance) pair, where
/// `e = estimate - truth`. Errors on a covariance that is not symmetric positive definite.
pub fn nees<const D: usize>(
    errors: &[SVector<f64, D>],
    covariances: &[SMatrix<f64, D, D>],
) -> Result<Vec<f64>, EvalError> {
    quarry_core::ensure_len(covariances.len(), errors.len(), "covariances vs errors")?;
    if errors.is_empty() {
        return Err(CoreError::Empty {
            what: "error series",
        }
        .into());
    }
    errors
        .iter()
        .zip(covariances)
        .map(|(e, p)| {
            quarry_core::ensure_finite(e.iter(), "estimation error")?;
            quarry_core::validate_covariance(p, "covariance")?;
            let chol = p
                .cholesky()
                .ok_or(CoreError::NotPositiveDefinite { what: "covariance" })?;
            Ok(e.dot(&chol.solve(e)))
        })
        .collect()
}

/// The outcome of the chi-square NEES consistency test (Bar-Shalom, Li & Kirubarajan 2001,
/// §5.4): under a consistent filter, the sum of N independent NEES values of dimension d is
/// chi-square with `N d` degrees of freedom, so the mean NEES lies in
/// `[chi2_ppf((1-q)/2, N d) / N, chi2_ppf((1+q)/2, N d) / N]` with probability q.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeesConsistency {
    /// The mean NEES.
    pub mean: f64,
    /// Lower end of the two-sided acceptance interval for the mean.
    pub lower: f64,
    /// Upper end of the acceptance interval.
    pub upper: f64,
    /// `lower <= mean <= upper`.
    pub consistent: bool,
}

/// Chi-square consistency test of a NEES series of state dimension `dim` at two-sided
/// confidence `confidence` (e.g. 0.95).
pub fn nees_consistency(
    nees: &[f64],
    dim: usize,
    confidence: f64,
) -> Result<NeesConsistency, EvalError> {
    if nees.is_empty() {
        return Err(CoreError::Empty {
            what: "NEES series",
        }
        .into());
    }
    quarry_core::ensure_finite(nees, "NEES series")?;
    if dim == 0 {
        return Err(CoreError::invalid("dim", "must be at least 1").into());
    }
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(CoreError::invalid(
            "confidence",
            format!("must lie in (0, 1), got {confidence}"),
        )
        .into());
    }
    let n = nees.len() as f64;
    let dof = n * dim as f64;
    let mean = nees.iter().sum::<f64>() / n;
    let lower = chi2_quantile((1.0 - confidence) / 2.0, dof)? / n;
    let upper = chi2_quantile(f64::midpoint(1.0, confidence), dof)? / n;
    Ok(NeesConsistency {
        mean,
        lower,
        upper,
        consistent: lower <= mean && mean <= upper,
    })
}

use quarry_core::stats::gamma_p;

/// Chi-square cumulative distribution `P(X <= x)` with `dof` degrees of freedom.
pub fn chi2_cdf(x: f64, dof: f64) -> Result<f64, EvalError> {
    if !(dof.is_finite() && dof > 0.0) {
        return Err(CoreError::invalid("dof", format!("must be finite and > 0, got {dof}")).into());
    }
    if x.is_nan() {
        return Err(CoreError::NonFinite { what: "x" }.into());
    }
    Ok(gamma_p(dof / 2.0, x.max(0.0) / 2.0))
}

/// Chi-square quantile (inverse CDF) for probability `p` in (0, 1), by bisection on
/// [`chi2_cdf`] to full double precision.
pub fn chi2_quantile(p: f64, dof: f64) -> Result<f64, EvalError> {
    if !(p > 0.0 && p < 1.0) {
        return Err(CoreError::invalid("p", format!("must lie in (0, 1), got {p}")).into());
    }
    chi2_cdf(0.0, dof)?;
    let mut lo = 0.0_f64;
    let mut hi = dof.max(1.0);
    while gamma_p(dof / 2.0, hi / 2.0) < p {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if gamma_p(dof / 2.0, mid / 2.0) < p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-15 * hi {
            break;
        }
    }
    Ok(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};
    use proptest::prelude::*;

    #[test]
    fn correlation_time_of_ar1() {
        // AR(1) e_k = φ e_{k−1} + w_k has ρ(τ) = φ^τ: below 1/e at τ = ⌈−1/ln φ⌉ (+ sampling noise)
        use rand::Rng;
        let mut rng = quarry_core::rng::seeded(3);
        let phi: f64 = 0.9;
        let mut e = vec![0.0];
        for _ in 0..20_000 {
            let w: f64 = rng.random::<f64>() - 0.5;
            e.push(phi * e[e.len() - 1] + w);
        }
        let tau = correlation_time(&e, 1.0).unwrap().unwrap();
        let expect = (-1.0 / phi.ln()).ceil();
        assert!((tau - expect).abs() <= 1.0, "{tau} vs {expect}");
        assert_eq!(correlation_time(&[2.0, 2.0, 2.0], 1.0).unwrap(), None);
        assert!(correlation_time(&[1.0], 1.0).is_err());
        assert!(correlation_time(&[1.0, f64::NAN], 1.0).is_err());
        assert!(correlation_time(&[1.0, 2.0], 0.0).is_err());
        // a linear ramp of n = 100 samples: ρ(τ) ≈ 1 − 3s + 2s³ with s = τ/n (continuum limit),
        // which reaches 1/e at s ≈ 0.218, i.e. τ ≈ 22
        let ramp: Vec<f64> = (0..100).map(f64::from).collect();
        let t = correlation_time(&ramp, 1.0).unwrap().unwrap();
        assert!((t - 22.0).abs() <= 1.0, "{t}");
    }

    proptest! {
        #[test]
        fn correlation_time_is_affine_invariant(
            e in proptest::collection::vec(-10.0f64..10.0, 3..60),
            a in 0.1f64..10.0,
            b in -5.0f64..5.0,
        ) {
            let t0 = correlation_time(&e, 0.2).unwrap();
            let f: Vec<f64> = e.iter().map(|v| a * v + b).collect();
            let t1 = correlation_time(&f, 0.2).unwrap();
            if let (Some(x), Some(y)) = (t0, t1) {
                prop_assert!((x - y).abs() < 1e-9);
                prop_assert!(x >= 0.2 && x <= 0.2 * e.len() as f64);
            }
        }
    }

    #[test]
    fn chi2_matches_scipy() {
        // scipy.stats.chi2.ppf / cdf (SciPy 1.17)
        let cases = [
            (0.95, 2.0, 5.991464547107979),
            (0.99, 4.0, 13.276704135987622),
            (0.025, 20.0, 9.590777392264868),
            (0.975, 20.0, 34.16960690283833),
            (0.5, 1.0, 0.454936423119572),
            (0.975, 2000.0, 2125.8423024497756),
        ];
        for (p, k, q) in cases {
            let got = chi2_quantile(p, k).unwrap();
            assert!(
                (got - q).abs() < 1e-9 * q,
                "ppf({p}, {k}) = {got}, want {q}"
            );
        }
        assert!((chi2_cdf(3.0, 3.0).unwrap() - 0.608_374_823_728_911).abs() < 1e-12);
        assert!(chi2_quantile(1.0, 2.0).is_err());
        assert!(chi2_cdf(1.0, 0.0).is_err());
    }

    #[test]
    fn rmse_and_errors() {
        assert!((rmse(&[3.0, 4.0]).unwrap() - 12.5f64.sqrt()).abs() < 1e-15);
        assert!(rmse(&[]).is_err());
        assert!(rmse(&[f64::NAN]).is_err());
        assert!(position_rmse(&[[0.0, 0.0]], &[[0.0, 0.0], [1.0, 1.0]]).is_err());
    }

    #[test]
    fn nees_rejects_bad_covariance() {
        let e = [Vector2::new(1.0, 0.0)];
        assert!(nees(&e, &[Matrix2::new(1.0, 2.0, 2.0, 1.0)]).is_err());
        assert!(nees(&e, &[Matrix2::new(1.0, 0.5, 0.0, 1.0)]).is_err());
        let q = nees(&e, &[Matrix2::new(2.0, 0.0, 0.0, 1.0)]).unwrap();
        assert!((q[0] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn consistency_flags_overconfident_filter() {
        let q = vec![8.0; 50]; // 2-D NEES averaging 8: covariance four times too small
        let c = nees_consistency(&q, 2, 0.95).unwrap();
        assert!(!c.consistent && c.mean > c.upper);
        let c = nees_consistency(&[2.0; 50], 2, 0.95).unwrap();
        assert!(c.consistent);
        assert!(nees_consistency(&q, 0, 0.95).is_err());
    }
}
