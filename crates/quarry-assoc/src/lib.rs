//! # quarry-assoc
//!
//! Data association for multi-target tracking, usable on its own: validation gates, optimal
//! assignment (GNN, Murty k-best), PDA, JPDA and JIPDA with track existence, and track
//! management.
//!
//! ```
//! use nalgebra::DMatrix;
//! use quarry_assoc::{Jipda, Jpda};
//! use quarry_core::{Associator, LikelihoodMatrix, TrackPrior};
//!
//! // ln g of 2 tracks × 3 detections; -inf = outside the gate.
//! let x = f64::NEG_INFINITY;
//! let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(2, 3, &[
//!     -2.0, -3.5,  x,
//!     -4.0, -2.2, -6.0,
//! ]))?;
//! let jpda = Jpda::new(0.9, 0.99, 1e-3)?;                 // P_D, P_G, clutter density κ
//! let a = jpda.associate(&lik, &[TrackPrior::default(); 2])?;
//! // β is n × (m + 1): column 0 is "missed", each row sums to 1.
//! assert!((a.beta.row(0).sum() - 1.0).abs() < 1e-12);
//! assert_eq!(a.beta[(0, 3)], 0.0);                        // not gated
//!
//! // JIPDA also updates each track's existence probability.
//! let prior = [TrackPrior { existence: Some(0.6), detection: None }; 2];
//! let b = Jipda::new(0.9, 0.99, 1e-3)?.associate(&lik, &prior)?;
//! assert!(b.existence.unwrap().iter().all(|&p| p > 0.6));
//! # Ok::<(), quarry_core::CoreError>(())
//! ```
//!
//! ## What is here
//!
//! - Gates ([`gate`]): [`ChiSquareGate`] (ellipsoidal, γ = χ²_Z⁻¹(P_G) for any dimension
//!   via [`chi2::chi2_quantile`]), [`RectGate`] (the circumscribing box, a cheap pre-gate),
//!   [`PositionVelocityGate`] (spec 003 eq. 8).
//! - Assignment ([`assign`]): [`assign::hungarian`] (rectangular, forbidden pairs = `+inf`),
//!   [`assign::hungarian_with_miss`] (GNN with per-row miss cost), [`assign::murty_k_best`].
//! - Associators implementing [`quarry_core::Associator`]: [`Gnn`], [`Pda`], [`Jpda`],
//!   [`Jipda`] (Musicki & Evans 2004), [`PaperLikelihood`] (spec 000's "paper" β, an ablation
//!   option; the correct forms are the defaults).
//! - Scale ([`engine`]): clusters = connected components of the gating graph; exact marginals
//!   per cluster by a memoised enumeration that never builds the product of hypotheses;
//!   k-best (Murty) and loopy belief propagation. **Automatic choice** ([`Method::Auto`], the
//!   default): a cluster is solved exactly while its DAG of distinct sub-problems has at most
//!   [`Solver::max_states`] nodes (2¹⁸ by default; in practice up to ~12–13 mutually gated
//!   targets with as many detections); larger clusters (or more than 128 tracks) use LBP.
//!   **LBP tolerance**: on random dense clusters (every pair gated) max |β_LBP − β_exact|
//!   ≤ 0.35 and mean error ≤ 0.2 (BP is over-confident there); exact on acyclic gating
//!   graphs; its ln c is the Bethe lower bound. See [`engine`].
//! - Track management ([`lifecycle`]): [`lifecycle::MOfN`], [`lifecycle::ExistenceThresholds`],
//!   [`lifecycle::ReplaceOnGateFailure`], [`lifecycle::TrackState`].
//!
//! ## Conventions and choices
//!
//! - Inputs are `ln g` ([`quarry_core::LikelihoodMatrix`]); all sums are done with per-row
//!   scaling and per-level rescaling, so likelihoods far below `f64` range are fine.
//! - If every joint event of a cluster has zero weight (P_D·P_G = 1 and a track with no usable
//!   detection), `log_normaliser = -inf` and those tracks get β_i0 = 1 (no update) — never NaN.
//! - A detection gated by no track is clutter; a track with no gated detection has β_i0 = 1.
//! - `P_D = 0` (per track via [`quarry_core::TrackPrior::detection`]) gives β_i0 = 1.
//!
//! ## Features
//!
//! None: the crate has no optional parts, and it uses quarry-core without quarry-core's default
//! features (`serde`, `rng`), so `--no-default-features` and the default build are the same lean
//! build. Enable `quarry-core/serde` to (de)serialise the core types it takes and returns.

pub mod assign;
mod associators;
pub mod chi2;
pub mod engine;
mod error;
pub mod gate;
pub mod lifecycle;

pub use associators::{Gnn, GnnCost, Jipda, Jpda, PaperLikelihood, Pda, weights_eq11};
pub use engine::{Method, Solver, clusters};
pub use error::AssocError;
pub use gate::{ChiSquareGate, PositionVelocityGate, PvState, RectGate};
