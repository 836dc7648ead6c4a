//! Set distances for multi-target estimates: OSPA (Schuhmacher, Vo & Vo 2008) and GOSPA with
//! alpha = 2 (Rahmathullah, García-Fernández & Svensson 2017), with GOSPA's decomposition into
//! localisation error, missed targets and false targets.
//!
//! Both take an order `p >= 1` and a cut-off `c > 0`; the optimal assignment is solved exactly
//! with [`crate::lsap`].
//!
//! ```
//! use quarry_eval::ospa::{gospa, ospa};
//! let truth = [[0.0, 0.0], [10.0, 0.0]];
//! let est = [[0.0, 1.0]];
//! // one localisation error of 1 and one missed target at cut-off 5, order 1
//! assert!((ospa(&truth, &est, 1.0, 5.0)? - 3.0).abs() < 1e-12);
//! let g = gospa(&truth, &est, 1.0, 5.0)?;
//! assert_eq!((g.missed, g.false_targets), (1, 0));
//! assert!((g.distance - (1.0 + 5.0 / 2.0)).abs() < 1e-12);
//! # Ok::<(), quarry_eval::EvalError>(())
//! ```

use quarry_core::CoreError;

use crate::EvalError;
use crate::lsap::linear_sum_assignment;

fn check<const N: usize>(x: &[[f64; N]], y: &[[f64; N]], p: f64, c: f64) -> Result<(), EvalError> {
    if !(p.is_finite() && p >= 1.0) {
        return Err(
            CoreError::invalid("p", format!("order must be finite and >= 1, got {p}")).into(),
        );
    }
    if !(c.is_finite() && c > 0.0) {
        return Err(
            CoreError::invalid("c", format!("cut-off must be finite and > 0, got {c}")).into(),
        );
    }
    quarry_core::ensure_finite(x.iter().flatten(), "first point set")?;
    quarry_core::ensure_finite(y.iter().flatten(), "second point set")?;
    Ok(())
}

fn dist<const N: usize>(a: &[f64; N], b: &[f64; N]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(u, v)| (u - v) * (u - v))
        .sum::<f64>()
        .sqrt()
}

/// Optimal assignment of `x` (rows) to `y` (columns) under `min(d, c)^p`; returns pairs and
/// their truncated costs.
fn assign<const N: usize>(
    x: &[[f64; N]],
    y: &[[f64; N]],
    p: f64,
    c: f64,
) -> Result<Vec<(usize, usize, f64)>, EvalError> {
    let (m, n) = (x.len(), y.len());
    let mut cost = Vec::with_capacity(m * n);
    for a in x {
        for b in y {
            cost.push(dist(a, b).min(c).powf(p));
        }
    }
    Ok(linear_sum_assignment(&cost, m, n)?
        .into_iter()
        .map(|(i, j)| (i, j, cost[i * n + j]))
        .collect())
}

/// OSPA distance of order `p` with cut-off `c` between two finite point sets.
///
/// `d = ( (min_pi sum_i min(d(x_i, y_pi(i)), c)^p + c^p |n - m|) / max(m, n) )^(1/p)`;
/// 0 when both sets are empty, `c` when exactly one is. OSPA is a metric on finite sets and is
/// bounded by `c`.
pub fn ospa<const N: usize>(
    x: &[[f64; N]],
    y: &[[f64; N]],
    p: f64,
    c: f64,
) -> Result<f64, EvalError> {
    check(x, y, p, c)?;
    let (m, n) = (x.len(), y.len());
    let big = m.max(n);
    if big == 0 {
        return Ok(0.0);
    }
    let loc: f64 = assign(x, y, p, c)?.iter().map(|t| t.2).sum();
    let card = c.powf(p) * (m.abs_diff(n)) as f64;
    Ok(((loc + card) / big as f64).powf(1.0 / p))
}

/// GOSPA (alpha = 2) and its decomposition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gospa {
    /// The GOSPA distance.
    pub distance: f64,
    /// Sum of `d^p` over the assigned pairs (those closer than `c`): the localisation part of
    /// `distance^p`.
    pub localisation: f64,
    /// Ground-truth points left unassigned (missed targets).
    pub missed: usize,
    /// Estimated points left unassigned (false targets).
    pub false_targets: usize,
    /// The pairs `(truth index, estimate index)` counted as assigned.
    pub assigned: usize,
}

/// GOSPA distance with alpha = 2 between the truth `x` and the estimates `y`:
/// `d^p = min over assignments of sum_assigned d^p + c^p / 2 (missed + false)`, where a pair is
/// assigned only when its distance is below `c`. `distance^p = localisation + c^p / 2 (missed +
/// false_targets)` holds exactly.
pub fn gospa<const N: usize>(
    x: &[[f64; N]],
    y: &[[f64; N]],
    p: f64,
    c: f64,
) -> Result<Gospa, EvalError> {
    check(x, y, p, c)?;
    let cp = c.powf(p);
    let mut localisation = 0.0;
    let mut assigned = 0;
    // With alpha = 2, leaving a pair unassigned costs c^p / 2 twice = c^p, so minimising
    // sum min(d, c)^p over full assignments gives the GOSPA optimum; pairs at d >= c are then
    // reported as one missed and one false target.
    for (i, j, _) in assign(x, y, p, c)? {
        let d = dist(&x[i], &y[j]);
        if d < c {
            localisation += d.powf(p);
            assigned += 1;
        }
    }
    let missed = x.len() - assigned;
    let false_targets = y.len() - assigned;
    let distance = (localisation + cp / 2.0 * (missed + false_targets) as f64).powf(1.0 / p);
    Ok(Gospa {
        distance,
        localisation,
        missed,
        false_targets,
        assigned,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn set() -> impl Strategy<Value = Vec<[f64; 2]>> {
        proptest::collection::vec([-10.0f64..10.0, -10.0f64..10.0], 0..6)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(96))]
        #[test]
        fn ospa_is_a_metric(a in set(), b in set(), c3 in set(), p in 1.0f64..3.0, cut in 0.5f64..8.0) {
            let ab = ospa(&a, &b, p, cut).unwrap();
            let ba = ospa(&b, &a, p, cut).unwrap();
            prop_assert!((ab - ba).abs() < 1e-9);
            prop_assert!(ab >= 0.0 && ab <= cut + 1e-12);
            prop_assert!(ospa(&a, &a, p, cut).unwrap() < 1e-9);
            if a.len() != b.len() { prop_assert!(ab > 0.0); }
            let ac = ospa(&a, &c3, p, cut).unwrap();
            let cb = ospa(&c3, &b, p, cut).unwrap();
            prop_assert!(ab <= ac + cb + 1e-9, "triangle: {} > {} + {}", ab, ac, cb);
        }

        #[test]
        fn gospa_decomposes(a in set(), b in set(), p in 1.0f64..3.0, cut in 0.5f64..8.0) {
            let g = gospa(&a, &b, p, cut).unwrap();
            let cp = cut.powf(p);
            let rebuilt = g.localisation + cp / 2.0 * (g.missed + g.false_targets) as f64;
            prop_assert!((g.distance.powf(p) - rebuilt).abs() < 1e-9 * (1.0 + rebuilt));
            prop_assert_eq!(g.missed + g.assigned, a.len());
            prop_assert_eq!(g.false_targets + g.assigned, b.len());
            let h = gospa(&b, &a, p, cut).unwrap();
            prop_assert!((g.distance - h.distance).abs() < 1e-9);
            prop_assert_eq!((g.missed, g.false_targets), (h.false_targets, h.missed));
        }
    }

    #[test]
    fn zero_only_for_equal_sets() {
        let a = [[0.0, 0.0], [1.0, 1.0]];
        assert_eq!(ospa(&a, &a, 2.0, 1.0).unwrap(), 0.0);
        assert!(ospa(&a, &[[0.0, 0.0], [1.0, 1.001]], 2.0, 1.0).unwrap() > 0.0);
        assert_eq!(ospa::<2>(&[], &[], 1.0, 3.0).unwrap(), 0.0);
        assert_eq!(ospa(&a, &[], 1.0, 3.0).unwrap(), 3.0);
        assert!(ospa(&a, &a, 0.5, 1.0).is_err());
        assert!(ospa(&a, &[[f64::NAN, 0.0]], 1.0, 1.0).is_err());
    }

    #[test]
    fn gospa_known_value() {
        // two truths, one estimate at distance 3 from the first, one far-away false target
        let x = [[0.0, 0.0], [10.0, 10.0]];
        let y = [[3.0, 0.0], [-20.0, 0.0]];
        let g = gospa(&x, &y, 2.0, 5.0).unwrap();
        assert_eq!((g.assigned, g.missed, g.false_targets), (1, 1, 1));
        assert!((g.localisation - 9.0).abs() < 1e-12);
        assert!((g.distance - (9.0f64 + 25.0).sqrt()).abs() < 1e-12);
    }
}
