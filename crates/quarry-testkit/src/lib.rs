//! # quarry-testkit
//!
//! Test support shared by the quarry crates' tests; a dev-dependency only (`publish = false`).
//!
//! - [`strategies`]: proptest strategies the tests kept writing again: image planes
//!   ([`strategies::plane`]), symmetric positive definite covariances of static size
//!   ([`strategies::spd_matrix`], [`strategies::spd_from_rotations`]), finite static vectors
//!   ([`strategies::finite_vector`]), dense matrices ([`strategies::matrix`]) and gated
//!   log-likelihood matrices for association ([`strategies::gated_log_likelihoods`]).
//! - [`brute`]: the brute-force references the property tests compare against: every
//!   assignment of a cost matrix ([`brute::assignments`], [`brute::lsap_cost`]), every JPDA joint
//!   event ([`brute::joint_events`], [`brute::jpda_marginals`], [`brute::best_event_log_weight`]),
//!   and linear-scan radius / nearest-neighbour queries ([`brute::within`],
//!   [`brute::nearest_distance`]).
//! - [`python`]: a pinned Python venv for the tests that read quarry's output back with Python
//!   tools ([`python::venv_or_skip`]); required in CI (`QUARRY_REQUIRE_PYTHON=1`).
//!
//! They are written for clarity, not speed: exponential enumeration, linear scans.
//!
//! ```
//! use nalgebra::DMatrix;
//! use proptest::prelude::*;
//! use quarry_testkit::{brute, strategies};
//!
//! // The cheapest complete assignment of a 2 x 2 cost matrix.
//! let cost = DMatrix::from_row_slice(2, 2, &[1.0, 4.0, 2.0, 1.0]);
//! assert_eq!(brute::assignments(&cost)[0], (2.0, vec![Some(0), Some(1)]));
//! assert_eq!(brute::lsap_cost(&[1.0, 4.0, 2.0, 1.0], 2, 2), 2.0);
//!
//! // Strategies plug into proptest! like any other.
//! proptest!(ProptestConfig::with_cases(8), |(p in strategies::spd_matrix::<3>(-2.0..2.0))| {
//!     prop_assert!(p.cholesky().is_some());
//! });
//! ```
//!
//! ## Features
//!
//! None.
//!
//! ## Use from quarry-core's own unit tests
//!
//! Don't: the kit depends on quarry-core, so a quarry-core unit test would see two copies of its
//! types. quarry-core's integration tests (`tests/`) may use it.

pub mod brute;
pub mod python;
pub mod strategies;
