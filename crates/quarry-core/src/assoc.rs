//! The data-association vocabulary: likelihood matrices, priors, and associators.

use crate::CoreError;
use nalgebra::DMatrix;

/// The gated log-likelihoods `ln g_ij` of `n` tracks (rows) against `m` detections (columns).
///
/// A pair outside the gate holds `f64::NEG_INFINITY`; every other entry is finite (NaN and
/// `+inf` are rejected at construction).
///
/// ```
/// use nalgebra::DMatrix;
/// use quarry_core::LikelihoodMatrix;
/// let l = LikelihoodMatrix::new(DMatrix::from_row_slice(1, 2, &[-1.0, f64::NEG_INFINITY])).unwrap();
/// assert!(l.gated(0, 0) && !l.gated(0, 1));
/// assert!(LikelihoodMatrix::new(DMatrix::from_row_slice(1, 1, &[f64::NAN])).is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct LikelihoodMatrix {
    log_lik: DMatrix<f64>,
}

impl LikelihoodMatrix {
    /// Wraps a matrix of log-likelihoods (`-inf` = outside the gate).
    pub fn new(log_lik: DMatrix<f64>) -> Result<Self, CoreError> {
        if log_lik.iter().any(|v| v.is_nan() || *v == f64::INFINITY) {
            return Err(CoreError::NonFinite {
                what: "likelihood matrix (NaN or +inf log-likelihood)",
            });
        }
        Ok(Self { log_lik })
    }

    /// Builds the matrix from `f(track, detection)`, which returns `None` outside the gate.
    pub fn from_fn(
        n_tracks: usize,
        n_meas: usize,
        mut f: impl FnMut(usize, usize) -> Option<f64>,
    ) -> Result<Self, CoreError> {
        Self::new(DMatrix::from_fn(n_tracks, n_meas, |i, j| {
            f(i, j).unwrap_or(f64::NEG_INFINITY)
        }))
    }

    /// Number of tracks (rows).
    pub fn n_tracks(&self) -> usize {
        self.log_lik.nrows()
    }
    /// Number of detections (columns).
    pub fn n_meas(&self) -> usize {
        self.log_lik.ncols()
    }
    /// `ln g_ij` (`-inf` outside the gate).
    #[inline]
    pub fn get(&self, track: usize, meas: usize) -> f64 {
        self.log_lik[(track, meas)]
    }
    /// True when detection `meas` is inside the gate of `track`.
    #[inline]
    pub fn gated(&self, track: usize, meas: usize) -> bool {
        self.log_lik[(track, meas)] > f64::NEG_INFINITY
    }
    /// The underlying matrix.
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.log_lik
    }
}

/// What an associator needs to know of each track besides its likelihoods.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TrackPrior {
    /// Predicted existence probability ψ⁻ (JIPDA); `None` = the track surely exists.
    pub existence: Option<f64>,
    /// Per-track detection probability, overriding the associator's `pd` (e.g. 0 outside the
    /// sensor's field of view).
    pub detection: Option<f64>,
}

/// The result of associating one scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Association {
    /// Marginal association probabilities, `n x (m + 1)`; column 0 is "missed" (β_i0), column
    /// `j + 1` is detection `j`. Each row sums to 1.
    pub beta: DMatrix<f64>,
    /// ln c, the log of the normaliser of the joint events (the target factor of an RBPF weight);
    /// GNN returns minus its total cost.
    pub log_normaliser: f64,
    /// Posterior existence probabilities (JIPDA).
    pub existence: Option<Vec<f64>>,
    /// Hard assignment (GNN): detection index per track, or `None`.
    pub assignment: Option<Vec<Option<usize>>>,
}

/// Turns gated likelihoods into an assignment (GNN) or marginal association probabilities with
/// a missed-detection column (PDA/JPDA/JIPDA).
pub trait Associator {
    /// Associates one scan. `prior` has one entry per track (row of `lik`).
    fn associate(
        &self,
        lik: &LikelihoodMatrix,
        prior: &[TrackPrior],
    ) -> Result<Association, CoreError>;
}
