//! The associators: [`Gnn`], [`Pda`], [`Jpda`], [`Jipda`] and the paper's simplified
//! [`PaperLikelihood`], all implementing quarry-core's [`Associator`].
//!
//! Scores (spec 000 §2.8): `L_i0 = 1 − P_D P_G ψ_i`, `L_ij = P_D ψ_i g_ij / κ` inside the gate
//! (ψ ≡ 1 for JPDA/PDA/GNN), with `g_ij = exp(lik[(i, j)])`, κ the clutter density, and `P_D`
//! overridden per track by [`TrackPrior::detection`].

use crate::AssocError;
use crate::engine::{self, Scores, Solver};
use crate::error::check_prob;
use crate::gate::check_prob_gate;
use nalgebra::DMatrix;
use quarry_core::{Association, Associator, CoreError, LikelihoodMatrix, TrackPrior};

/// Checks the common inputs and returns the per-track detection probabilities.
fn common(
    lik: &LikelihoodMatrix,
    prior: &[TrackPrior],
    pd: f64,
    prob_gate: f64,
    clutter_density: f64,
) -> Result<Vec<f64>, CoreError> {
    quarry_core::ensure_len(
        prior.len(),
        lik.n_tracks(),
        "track priors (one per likelihood row)",
    )?;
    check_params(pd, prob_gate, clutter_density)?;
    prior
        .iter()
        .map(|p| {
            let d = p.detection.unwrap_or(pd);
            check_prob("TrackPrior::detection", d, false)?;
            if let Some(e) = p.existence {
                check_prob("TrackPrior::existence", e, false)?;
            }
            Ok(d)
        })
        .collect()
}

fn check_params(pd: f64, prob_gate: f64, clutter_density: f64) -> Result<(), CoreError> {
    check_prob("pd", pd, false)?;
    check_prob_gate(prob_gate)?;
    if !(clutter_density.is_finite() && clutter_density > 0.0) {
        return Err(CoreError::invalid(
            "clutter_density",
            format!("{clutter_density} must be positive and finite"),
        ));
    }
    Ok(())
}

fn ln_or_neg_inf(x: f64) -> f64 {
    if x > 0.0 { x.ln() } else { f64::NEG_INFINITY }
}

/// Joint Probabilistic Data Association (Bar-Shalom & Fortmann), exact by default.
///
/// Output: β (`n × (m+1)`, column 0 = missed, rows sum to 1), `log_normaliser` = ln c of the
/// unscaled scores (the Rao-Blackwellised target factor of spec 000 §2.10). Existence priors
/// are ignored (use [`Jipda`]).
///
/// ```
/// use nalgebra::DMatrix;
/// use quarry_assoc::Jpda;
/// use quarry_core::{Associator, LikelihoodMatrix, TrackPrior};
/// let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(2, 2, &[-1.0, -3.0, -2.0, -1.5]))?;
/// let a = Jpda::new(0.9, 0.99, 1e-3)?.associate(&lik, &[TrackPrior::default(); 2])?;
/// for i in 0..2 { assert!((a.beta.row(i).sum() - 1.0).abs() < 1e-12); }
/// # Ok::<(), quarry_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jpda {
    /// Detection probability P_D (a [`TrackPrior::detection`] overrides it per track).
    pub pd: f64,
    /// Gate probability P_G (the probability mass inside the gate used to build the matrix).
    pub prob_gate: f64,
    /// Clutter spatial density κ (per unit measurement volume).
    pub clutter_density: f64,
    /// Per-cluster algorithm and budgets.
    pub solver: Solver,
}

impl Jpda {
    /// Validated constructor with the default [`Solver`].
    pub fn new(pd: f64, prob_gate: f64, clutter_density: f64) -> Result<Self, CoreError> {
        check_params(pd, prob_gate, clutter_density)?;
        Ok(Self {
            pd,
            prob_gate,
            clutter_density,
            solver: Solver::default(),
        })
    }

    /// The same associator with another solver.
    pub fn with_solver(mut self, solver: Solver) -> Self {
        self.solver = solver;
        self
    }
}

impl Associator for Jpda {
    fn associate(
        &self,
        lik: &LikelihoodMatrix,
        prior: &[TrackPrior],
    ) -> Result<Association, CoreError> {
        let pds = common(lik, prior, self.pd, self.prob_gate, self.clutter_density)?;
        let ln_k = self.clutter_density.ln();
        let sc = Scores {
            lik,
            ln_miss: pds
                .iter()
                .map(|&d| ln_or_neg_inf(1.0 - d * self.prob_gate))
                .collect(),
            ln_coef: pds.iter().map(|&d| ln_or_neg_inf(d) - ln_k).collect(),
        };
        let m = engine::marginals(&sc, &self.solver)?;
        Ok(Association {
            beta: m.beta,
            log_normaliser: m.ln_c,
            existence: None,
            assignment: None,
        })
    }
}

/// Joint Integrated PDA (Musicki & Evans 2004) with track existence.
///
/// `ψ⁻_i = survival · existence_i` (existence `None` = 1; leave `survival = 1` when the priors
/// are already predicted). Scores `L_i0 = 1 − P_D P_G ψ⁻`, `L_ij = P_D ψ⁻ g_ij/κ`; the same
/// enumeration as [`Jpda`] gives unconditional marginals β̃, then (spec 000 §2.8)
/// `ψ⁺ = β̃_0 (1 − P_D P_G) ψ⁻ / (1 − P_D P_G ψ⁻) + Σ_j β̃_j`, and the returned β is conditioned
/// on existence: `β_0 = β̃_0 (1 − P_D P_G) ψ⁻ / ((1 − P_D P_G ψ⁻) ψ⁺)`, `β_j = β̃_j / ψ⁺`
/// (rows sum to 1). With ψ⁻ ≡ 1 it is exactly [`Jpda`]. A track with ψ⁻ = 0 gets β_0 = 1, ψ⁺ = 0.
///
/// ```
/// use nalgebra::DMatrix;
/// use quarry_assoc::Jipda;
/// use quarry_core::{Associator, LikelihoodMatrix, TrackPrior};
/// let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(1, 1, &[f64::NEG_INFINITY]))?;
/// let prior = [TrackPrior { existence: Some(0.5), detection: None }];
/// let a = Jipda::new(0.9, 0.99, 1e-3)?.associate(&lik, &prior)?;
/// let pdpg = 0.9 * 0.99;
/// let want = (1.0 - pdpg) * 0.5 / (1.0 - pdpg * 0.5);   // no detection: existence drops
/// assert!((a.existence.unwrap()[0] - want).abs() < 1e-12);
/// # Ok::<(), quarry_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jipda {
    /// Detection probability P_D.
    pub pd: f64,
    /// Gate probability P_G.
    pub prob_gate: f64,
    /// Clutter spatial density κ.
    pub clutter_density: f64,
    /// Survival probability p_S applied to the given existence (1 = priors already predicted).
    pub survival: f64,
    /// Per-cluster algorithm and budgets.
    pub solver: Solver,
}

impl Jipda {
    /// Validated constructor, `survival = 1`, default [`Solver`].
    pub fn new(pd: f64, prob_gate: f64, clutter_density: f64) -> Result<Self, CoreError> {
        check_params(pd, prob_gate, clutter_density)?;
        Ok(Self {
            pd,
            prob_gate,
            clutter_density,
            survival: 1.0,
            solver: Solver::default(),
        })
    }

    /// Sets the survival probability p_S.
    pub fn with_survival(mut self, survival: f64) -> Self {
        self.survival = survival;
        self
    }

    /// The same associator with another solver.
    pub fn with_solver(mut self, solver: Solver) -> Self {
        self.solver = solver;
        self
    }
}

impl Associator for Jipda {
    fn associate(
        &self,
        lik: &LikelihoodMatrix,
        prior: &[TrackPrior],
    ) -> Result<Association, CoreError> {
        let pds = common(lik, prior, self.pd, self.prob_gate, self.clutter_density)?;
        check_prob("survival", self.survival, false)?;
        let psi: Vec<f64> = prior
            .iter()
            .map(|p| self.survival * p.existence.unwrap_or(1.0))
            .collect();
        let ln_k = self.clutter_density.ln();
        let sc = Scores {
            lik,
            ln_miss: pds
                .iter()
                .zip(&psi)
                .map(|(&d, &s)| ln_or_neg_inf(1.0 - d * self.prob_gate * s))
                .collect(),
            ln_coef: pds
                .iter()
                .zip(&psi)
                .map(|(&d, &s)| ln_or_neg_inf(d * s) - ln_k)
                .collect(),
        };
        let mut mg = engine::marginals(&sc, &self.solver)?;
        let n = lik.n_tracks();
        let mut existence = Vec::with_capacity(n);
        for i in 0..n {
            let dpg = pds[i] * self.prob_gate;
            let den = 1.0 - dpg * psi[i];
            let r = if den > 0.0 {
                (1.0 - dpg) * psi[i] / den
            } else {
                0.0
            };
            let b0 = mg.beta[(i, 0)];
            let det: f64 = mg.beta.row(i).iter().skip(1).sum();
            let post = (b0 * r + det).clamp(0.0, 1.0);
            existence.push(post);
            if post > 0.0 {
                mg.beta[(i, 0)] = b0 * r / post;
                for j in 1..mg.beta.ncols() {
                    mg.beta[(i, j)] /= post;
                }
            } else {
                mg.beta.row_mut(i).fill(0.0);
                mg.beta[(i, 0)] = 1.0;
            }
        }
        Ok(Association {
            beta: mg.beta,
            log_normaliser: mg.ln_c,
            existence: Some(existence),
            assignment: None,
        })
    }
}

/// Probabilistic Data Association for each track alone (no exclusivity between tracks):
/// `β_ij ∝ L_ij`, `β_i0 ∝ L_i0` within each row; `log_normaliser = Σ_i ln Σ_j L_ij` (j = 0..m).
///
/// ```
/// use nalgebra::DMatrix;
/// use quarry_assoc::Pda;
/// use quarry_core::{Associator, LikelihoodMatrix, TrackPrior};
/// let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(1, 2, &[0.0, f64::NEG_INFINITY]))?;
/// let pda = Pda { pd: 0.5, prob_gate: 0.99, clutter_density: 1.0 };
/// let a = pda.associate(&lik, &[TrackPrior::default()])?;
/// // L_0 = 1 - 0.495, L_1 = 0.5 · e⁰ / 1.
/// assert!((a.beta[(0, 1)] - 0.5 / (0.505 + 0.5)).abs() < 1e-12);
/// # Ok::<(), quarry_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pda {
    /// Detection probability P_D.
    pub pd: f64,
    /// Gate probability P_G.
    pub prob_gate: f64,
    /// Clutter spatial density κ.
    pub clutter_density: f64,
}

impl Associator for Pda {
    fn associate(
        &self,
        lik: &LikelihoodMatrix,
        prior: &[TrackPrior],
    ) -> Result<Association, CoreError> {
        let pds = common(lik, prior, self.pd, self.prob_gate, self.clutter_density)?;
        let (n, m) = (lik.n_tracks(), lik.n_meas());
        let ln_k = self.clutter_density.ln();
        let mut beta = DMatrix::zeros(n, m + 1);
        let mut ln_c = 0.0;
        let mut row = vec![0.0; m + 1];
        for i in 0..n {
            let lc = ln_or_neg_inf(pds[i]) - ln_k;
            row[0] = ln_or_neg_inf(1.0 - pds[i] * self.prob_gate);
            for j in 0..m {
                let g = lik.get(i, j);
                row[j + 1] = if g == f64::NEG_INFINITY || lc == f64::NEG_INFINITY {
                    f64::NEG_INFINITY
                } else {
                    lc + g
                };
            }
            let mx = row.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if mx == f64::NEG_INFINITY {
                beta[(i, 0)] = 1.0;
                ln_c = f64::NEG_INFINITY;
                continue;
            }
            let tot: f64 = row.iter().map(|x| (x - mx).exp()).sum();
            for j in 0..=m {
                beta[(i, j)] = (row[j] - mx).exp() / tot;
            }
            ln_c += mx + tot.ln();
        }
        Ok(Association {
            beta,
            log_normaliser: ln_c,
            existence: None,
            assignment: None,
        })
    }
}

/// The paper's simplified coefficients (spec 000 §2.8 mode `Paper`, eqs. 5/11/12), for
/// ablation only: `β_ij = g_ij / Σ_{j'} g_ij'` over the gated detections, `β_i0 = 0` (or 1 when
/// nothing is gated — the spec's guard), and `log_normaliser` = ln of eq. (11),
/// [`weights_eq11`]. No missed-detection, clutter or exclusivity model.
///
/// ```
/// use nalgebra::DMatrix;
/// use quarry_assoc::PaperLikelihood;
/// use quarry_core::{Associator, LikelihoodMatrix, TrackPrior};
/// let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(1, 2, &[0.0, 2f64.ln()]))?;
/// let a = PaperLikelihood.associate(&lik, &[TrackPrior::default()])?;
/// assert!((a.beta[(0, 2)] - 2.0 / 3.0).abs() < 1e-12 && a.beta[(0, 0)] == 0.0);
/// # Ok::<(), quarry_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PaperLikelihood;

impl Associator for PaperLikelihood {
    fn associate(
        &self,
        lik: &LikelihoodMatrix,
        prior: &[TrackPrior],
    ) -> Result<Association, CoreError> {
        quarry_core::ensure_len(
            prior.len(),
            lik.n_tracks(),
            "track priors (one per likelihood row)",
        )?;
        let (n, m) = (lik.n_tracks(), lik.n_meas());
        let mut beta = DMatrix::zeros(n, m + 1);
        for i in 0..n {
            let mx = (0..m)
                .map(|j| lik.get(i, j))
                .fold(f64::NEG_INFINITY, f64::max);
            if mx == f64::NEG_INFINITY {
                beta[(i, 0)] = 1.0;
                continue;
            }
            let tot: f64 = (0..m).map(|j| (lik.get(i, j) - mx).exp()).sum();
            for j in 0..m {
                beta[(i, j + 1)] = (lik.get(i, j) - mx).exp() / tot;
            }
        }
        Ok(Association {
            beta,
            log_normaliser: weights_eq11(lik),
            existence: None,
            assignment: None,
        })
    }
}

/// ln of the paper's eq. (11) target weight: `Σ_j [LSE_i(2 ln g_ij) − LSE_i(ln g_ij)]` over the
/// detections with at least one finite entry (pass an ungated matrix for the literal form).
/// Finite even when every `g` underflows (or overflows) in linear space: each column is
/// evaluated as `M + ln Σ e^{2(x−M)} − ln Σ e^{x−M}` with `M` its largest entry.
pub fn weights_eq11(lik: &LikelihoodMatrix) -> f64 {
    let (n, m) = (lik.n_tracks(), lik.n_meas());
    let mut total = 0.0;
    for j in 0..m {
        let mx = (0..n)
            .map(|i| lik.get(i, j))
            .fold(f64::NEG_INFINITY, f64::max);
        if mx == f64::NEG_INFINITY {
            continue;
        }
        let (mut s1, mut s2) = (0.0, 0.0);
        for i in 0..n {
            let d = lik.get(i, j) - mx;
            s1 += d.exp();
            s2 += (2.0 * d).exp();
        }
        total += mx + s2.ln() - s1.ln();
    }
    total
}

/// How [`Gnn`] scores a track–detection pair.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum GnnCost {
    /// The most likely joint event under the JPDA scores (cost `−ln L_ij`, missed `−ln L_i0`).
    #[default]
    JointEvent,
    /// As many pairs as possible, then the least total `−ln g_ij` (a classic rectangular
    /// assignment on the gated pairs).
    MaxCardinality,
}

/// Global Nearest Neighbour: the optimal one-to-one assignment (Hungarian / shortest augmenting
/// path) on the gated pairs. β is 0/1, `assignment` is set, and `log_normaliser` is minus the
/// total cost (`Σ ln L` of the chosen event for [`GnnCost::JointEvent`]).
///
/// ```
/// use nalgebra::DMatrix;
/// use quarry_assoc::Gnn;
/// use quarry_core::{Associator, LikelihoodMatrix, TrackPrior};
/// let x = f64::NEG_INFINITY;
/// let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(2, 2, &[-1.0, -2.0, -1.5, x]))?;
/// let a = Gnn::new(0.9, 0.99, 1e-3)?.associate(&lik, &[TrackPrior::default(); 2])?;
/// assert_eq!(a.assignment.unwrap(), vec![Some(1), Some(0)]);
/// # Ok::<(), quarry_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gnn {
    /// Detection probability P_D.
    pub pd: f64,
    /// Gate probability P_G.
    pub prob_gate: f64,
    /// Clutter spatial density κ.
    pub clutter_density: f64,
    /// Cost model.
    pub cost: GnnCost,
}

impl Gnn {
    /// Validated constructor with [`GnnCost::JointEvent`].
    pub fn new(pd: f64, prob_gate: f64, clutter_density: f64) -> Result<Self, CoreError> {
        check_params(pd, prob_gate, clutter_density)?;
        Ok(Self {
            pd,
            prob_gate,
            clutter_density,
            cost: GnnCost::JointEvent,
        })
    }

    /// Solves the assignment and returns (row → column, total cost).
    pub fn solve(
        &self,
        lik: &LikelihoodMatrix,
        prior: &[TrackPrior],
    ) -> Result<crate::assign::Assignment, AssocError> {
        let pds = common(lik, prior, self.pd, self.prob_gate, self.clutter_density)?;
        let (n, m) = (lik.n_tracks(), lik.n_meas());
        let ln_k = self.clutter_density.ln();
        match self.cost {
            GnnCost::JointEvent => {
                let cost = DMatrix::from_fn(n, m, |i, j| {
                    let g = lik.get(i, j);
                    let lc = ln_or_neg_inf(pds[i]) - ln_k;
                    if g == f64::NEG_INFINITY || lc == f64::NEG_INFINITY {
                        f64::INFINITY
                    } else {
                        -(lc + g)
                    }
                });
                let miss: Vec<f64> = pds
                    .iter()
                    .map(|&d| -ln_or_neg_inf(1.0 - d * self.prob_gate))
                    .collect();
                match crate::assign::hungarian_with_miss(&cost, &miss) {
                    Err(AssocError::Infeasible(_)) => Ok(crate::assign::Assignment {
                        // Every track has P_D·P_G = 1 and no usable detection: impossible event.
                        row_to_col: vec![None; n],
                        cost: f64::INFINITY,
                    }),
                    r => r,
                }
            }
            GnnCost::MaxCardinality => {
                let cost = DMatrix::from_fn(n, m, |i, j| {
                    let g = lik.get(i, j);
                    if g == f64::NEG_INFINITY {
                        f64::INFINITY
                    } else {
                        -g
                    }
                });
                let finite = cost.iter().copied().filter(|c| c.is_finite());
                let lo = finite.clone().fold(f64::INFINITY, f64::min);
                let span: f64 = (0..n)
                    .map(|i| {
                        (0..m)
                            .map(|j| cost[(i, j)] - lo)
                            .filter(|c| c.is_finite())
                            .fold(0.0, f64::max)
                    })
                    .sum();
                let shifted = cost.map(|c| c - if lo.is_finite() { lo } else { 0.0 });
                let miss = vec![1.0 + span; n];
                let a = crate::assign::hungarian_with_miss(&shifted, &miss)?;
                let total = a
                    .row_to_col
                    .iter()
                    .enumerate()
                    .filter_map(|(i, c)| c.map(|j| cost[(i, j)]))
                    .sum();
                Ok(crate::assign::Assignment {
                    row_to_col: a.row_to_col,
                    cost: total,
                })
            }
        }
    }
}

impl Associator for Gnn {
    fn associate(
        &self,
        lik: &LikelihoodMatrix,
        prior: &[TrackPrior],
    ) -> Result<Association, CoreError> {
        let a = self.solve(lik, prior)?;
        let (n, m) = (lik.n_tracks(), lik.n_meas());
        let mut beta = DMatrix::zeros(n, m + 1);
        for (i, c) in a.row_to_col.iter().enumerate() {
            beta[(i, c.map_or(0, |j| j + 1))] = 1.0;
        }
        Ok(Association {
            beta,
            log_normaliser: -a.cost,
            existence: None,
            assignment: Some(a.row_to_col),
        })
    }
}
