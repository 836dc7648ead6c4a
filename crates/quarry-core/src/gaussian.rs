//! The one Gaussian type.

use crate::CoreError;
use nalgebra::{Cholesky, SMatrix, SVector};

/// Relative tolerance of the symmetry check in [`Gaussian::try_new`].
pub const SYMMETRY_TOL: f64 = 1e-9;

/// A multivariate normal N(mean, cov) of fixed dimension `D`.
///
/// The fields are public so filters can update them in place; [`Gaussian::try_new`] and
/// [`Gaussian::validate`] check the invariant (finite, symmetric, positive definite) wherever data
/// enter from outside.
///
/// ```
/// use nalgebra::{Matrix2, Vector2};
/// use quarry_core::Gaussian;
/// let g = Gaussian::try_new(Vector2::new(1.0, 2.0), Matrix2::new(4.0, 0.0, 0.0, 1.0)).unwrap();
/// assert!((g.mahalanobis2(&Vector2::new(3.0, 2.0)).unwrap() - 1.0).abs() < 1e-12);
/// assert!(Gaussian::try_new(Vector2::zeros(), Matrix2::new(1.0, 2.0, 2.0, 1.0)).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Gaussian<const D: usize> {
    /// The mean.
    pub mean: SVector<f64, D>,
    /// The covariance (symmetric positive definite).
    pub cov: SMatrix<f64, D, D>,
}

impl<const D: usize> Gaussian<D> {
    /// A validated Gaussian: finite mean and covariance, covariance symmetric (to a relative
    /// [`SYMMETRY_TOL`]) and positive definite (Cholesky succeeds). The covariance is symmetrised.
    pub fn try_new(mean: SVector<f64, D>, cov: SMatrix<f64, D, D>) -> Result<Self, CoreError> {
        let mut g = Self { mean, cov };
        g.validate()?;
        g.symmetrize();
        Ok(g)
    }

    /// A Gaussian without validation, for hot paths whose inputs are already checked.
    pub fn new_unchecked(mean: SVector<f64, D>, cov: SMatrix<f64, D, D>) -> Self {
        Self { mean, cov }
    }

    /// Checks the invariant: finite values, symmetric, positive definite.
    pub fn validate(&self) -> Result<(), CoreError> {
        if !self.mean.iter().all(|v| v.is_finite()) {
            return Err(CoreError::NonFinite {
                what: "Gaussian mean",
            });
        }
        validate_covariance(&self.cov, "Gaussian covariance")
    }

    /// Replaces the covariance by `(P + Pᵀ) / 2`.
    pub fn symmetrize(&mut self) {
        self.cov = (self.cov + self.cov.transpose()) * 0.5;
    }

    /// The Cholesky factor of the covariance, or [`CoreError::NotPositiveDefinite`].
    pub fn cholesky(&self) -> Result<Cholesky<f64, nalgebra::Const<D>>, CoreError> {
        Cholesky::new(self.cov).ok_or(CoreError::NotPositiveDefinite {
            what: "Gaussian covariance",
        })
    }

    /// Squared Mahalanobis distance `(x - mean)ᵀ cov⁻¹ (x - mean)`.
    pub fn mahalanobis2(&self, x: &SVector<f64, D>) -> Result<f64, CoreError> {
        let chol = self.cholesky()?;
        let d = x - self.mean;
        let y = chol
            .l()
            .solve_lower_triangular(&d)
            .ok_or(CoreError::NotPositiveDefinite {
                what: "Gaussian covariance",
            })?;
        Ok(y.norm_squared())
    }

    /// Natural log of the density at `x`.
    pub fn log_pdf(&self, x: &SVector<f64, D>) -> Result<f64, CoreError> {
        let chol = self.cholesky()?;
        let d = x - self.mean;
        let l = chol.l();
        let y = l
            .solve_lower_triangular(&d)
            .ok_or(CoreError::NotPositiveDefinite {
                what: "Gaussian covariance",
            })?;
        let log_det: f64 = 2.0 * l.diagonal().iter().map(|v| v.ln()).sum::<f64>();
        Ok(-0.5 * (y.norm_squared() + log_det + D as f64 * (2.0 * std::f64::consts::PI).ln()))
    }
}

/// Checks that a covariance matrix is finite, symmetric (relative tolerance [`SYMMETRY_TOL`]) and
/// positive definite. `what` names the matrix in the error.
pub fn validate_covariance<const D: usize>(
    cov: &SMatrix<f64, D, D>,
    what: &'static str,
) -> Result<(), CoreError> {
    if !cov.iter().all(|v| v.is_finite()) {
        return Err(CoreError::NonFinite { what });
    }
    let scale = cov.amax().max(f64::MIN_POSITIVE);
    for i in 0..D {
        for j in (i + 1)..D {
            if (cov[(i, j)] - cov[(j, i)]).abs() > SYMMETRY_TOL * scale {
                return Err(CoreError::NotPositiveDefinite { what });
            }
        }
    }
    if Cholesky::new(*cov).is_none() {
        return Err(CoreError::NotPositiveDefinite { what });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    #[test]
    fn log_pdf_standard_normal() {
        let g = Gaussian::try_new(Vector2::zeros(), Matrix2::identity()).unwrap();
        let lp = g.log_pdf(&Vector2::zeros()).unwrap();
        assert!((lp + (2.0 * std::f64::consts::PI).ln()).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_covariances() {
        assert!(matches!(
            Gaussian::try_new(Vector2::zeros(), Matrix2::new(1.0, 0.5, 0.4, 1.0)),
            Err(CoreError::NotPositiveDefinite { .. })
        ));
        assert!(matches!(
            Gaussian::try_new(Vector2::new(f64::NAN, 0.0), Matrix2::identity()),
            Err(CoreError::NonFinite { .. })
        ));
        assert!(Gaussian::try_new(Vector2::zeros(), Matrix2::new(1.0, 0.0, 0.0, 0.0)).is_err());
    }
}
