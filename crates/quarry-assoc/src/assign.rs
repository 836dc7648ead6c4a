//! Optimal assignment: the Hungarian method (shortest augmenting paths with potentials, the
//! Jonker–Volgenant / Kuhn–Munkres family, O(n²m)) on rectangular cost matrices with forbidden
//! pairs, and Murty's k-best assignments.
//!
//! Costs are `f64`; `+inf` marks a forbidden pair. NaN and `-inf` are errors.
//!
//! ```
//! use nalgebra::DMatrix;
//! use quarry_assoc::assign::{hungarian, murty_k_best};
//! let inf = f64::INFINITY;
//! let c = DMatrix::from_row_slice(2, 3, &[4.0, 1.0, 3.0,
//!                                         2.0, inf, 5.0]);
//! let a = hungarian(&c)?;
//! assert_eq!(a.row_to_col, vec![Some(1), Some(0)]);
//! assert_eq!(a.cost, 3.0);
//! let best = murty_k_best(&c, 3)?;
//! assert_eq!(best.iter().map(|a| a.cost).collect::<Vec<_>>(), vec![3.0, 5.0, 6.0]);
//! # Ok::<(), quarry_assoc::AssocError>(())
//! ```

use crate::AssocError;
use nalgebra::DMatrix;
use quarry_core::CoreError;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A solution of an assignment problem.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// Column assigned to each row (`None` for a row left unassigned when rows > columns, or a
    /// missed row in [`hungarian_with_miss`]).
    pub row_to_col: Vec<Option<usize>>,
    /// The total cost (sum of the chosen entries, plus miss costs where used).
    pub cost: f64,
}

fn check_costs(cost: &DMatrix<f64>) -> Result<(), AssocError> {
    if cost.iter().any(|v| v.is_nan() || *v == f64::NEG_INFINITY) {
        return Err(CoreError::NonFinite {
            what: "assignment cost matrix (NaN or -inf)",
        }
        .into());
    }
    Ok(())
}

/// Minimum-cost assignment of `min(rows, cols)` pairs, never using a forbidden (`+inf`) pair.
///
/// Every row is assigned when `rows <= cols`, every column otherwise. Returns
/// [`AssocError::Infeasible`] when no such assignment avoids the forbidden pairs. An empty
/// matrix gives an empty assignment of cost 0.
pub fn hungarian(cost: &DMatrix<f64>) -> Result<Assignment, AssocError> {
    check_costs(cost)?;
    let (n, m) = cost.shape();
    if n <= m {
        let cols = solve_rows_le_cols(n, m, |i, j| cost[(i, j)])?;
        Ok(finish(cost, cols))
    } else {
        let rows_of_col = solve_rows_le_cols(m, n, |i, j| cost[(j, i)])?;
        let mut row_to_col = vec![None; n];
        for (c, r) in rows_of_col.iter().enumerate() {
            if let Some(r) = r {
                row_to_col[*r] = Some(c);
            }
        }
        Ok(finish(cost, row_to_col))
    }
}

fn finish(cost: &DMatrix<f64>, row_to_col: Vec<Option<usize>>) -> Assignment {
    let total = row_to_col
        .iter()
        .enumerate()
        .filter_map(|(i, c)| c.map(|j| cost[(i, j)]))
        .sum();
    Assignment {
        row_to_col,
        cost: total,
    }
}

/// Core solver for `n <= m`; returns the column of each row.
fn solve_rows_le_cols(
    n: usize,
    m: usize,
    a: impl Fn(usize, usize) -> f64,
) -> Result<Vec<Option<usize>>, AssocError> {
    debug_assert!(n <= m);
    if n == 0 {
        return Ok(Vec::new());
    }
    let inf = f64::INFINITY;
    let mut u = vec![0.0; n + 1];
    let mut v = vec![0.0; m + 1];
    let mut p = vec![0usize; m + 1]; // p[j] = row (1-based) assigned to column j
    let mut way = vec![0usize; m + 1];
    let mut minv = vec![inf; m + 1];
    let mut used = vec![false; m + 1];
    for i in 1..=n {
        p[0] = i;
        let mut j0 = 0usize;
        minv.fill(inf);
        used.fill(false);
        loop {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = inf;
            let mut j1 = 0usize;
            for j in 1..=m {
                if !used[j] {
                    let cur = a(i0 - 1, j - 1) - u[i0] - v[j];
                    if cur < minv[j] {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if minv[j] < delta {
                        delta = minv[j];
                        j1 = j;
                    }
                }
            }
            if delta == inf || j1 == 0 {
                return Err(AssocError::Infeasible(format!(
                    "row {} cannot be assigned without a forbidden pair",
                    i - 1
                )));
            }
            for j in 0..=m {
                if used[j] {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else if minv[j] < inf {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if p[j0] == 0 {
                break;
            }
        }
        loop {
            let j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    let mut out = vec![None; n];
    for j in 1..=m {
        if p[j] != 0 {
            out[p[j] - 1] = Some(j - 1);
        }
    }
    Ok(out)
}

/// Builds the `n × (m + n)` matrix whose extra column `m + i` is row `i`'s "unassigned" option
/// at `miss_cost[i]` (the other extra columns are forbidden).
pub fn augment_with_miss(
    cost: &DMatrix<f64>,
    miss_cost: &[f64],
) -> Result<DMatrix<f64>, AssocError> {
    let (n, m) = cost.shape();
    quarry_core::ensure_len(miss_cost.len(), n, "miss_cost")?;
    if miss_cost
        .iter()
        .any(|c| c.is_nan() || *c == f64::NEG_INFINITY)
    {
        return Err(CoreError::NonFinite { what: "miss_cost" }.into());
    }
    Ok(DMatrix::from_fn(n, m + n, |i, j| {
        if j < m {
            cost[(i, j)]
        } else if j - m == i {
            miss_cost[i]
        } else {
            f64::INFINITY
        }
    }))
}

fn strip_miss(a: Assignment, m: usize) -> Assignment {
    Assignment {
        row_to_col: a
            .row_to_col
            .into_iter()
            .map(|c| c.filter(|&j| j < m))
            .collect(),
        cost: a.cost,
    }
}

/// Minimum-cost assignment where row `i` may also stay unassigned at cost `miss_cost[i]` (the
/// GNN problem: "forbidden" pairs and unmatched tracks handled, any shape).
pub fn hungarian_with_miss(
    cost: &DMatrix<f64>,
    miss_cost: &[f64],
) -> Result<Assignment, AssocError> {
    let aug = augment_with_miss(cost, miss_cost)?;
    Ok(strip_miss(hungarian(&aug)?, cost.ncols()))
}

/// The k best assignments of [`hungarian_with_miss`]'s problem, in order of increasing cost.
pub fn murty_k_best_with_miss(
    cost: &DMatrix<f64>,
    miss_cost: &[f64],
    k: usize,
) -> Result<Vec<Assignment>, AssocError> {
    let aug = augment_with_miss(cost, miss_cost)?;
    let m = cost.ncols();
    Ok(murty_k_best(&aug, k)?
        .into_iter()
        .map(|a| strip_miss(a, m))
        .collect())
}

struct Node {
    cost: f64,
    seq: usize,
    sol: Vec<Option<usize>>,
    forced: Vec<(usize, usize)>,
    forbidden: Vec<(usize, usize)>,
}
impl PartialEq for Node {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Node {}
impl PartialOrd for Node {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Node {
    fn cmp(&self, o: &Self) -> Ordering {
        // Min-heap on (cost, seq).
        o.cost.total_cmp(&self.cost).then(o.seq.cmp(&self.seq))
    }
}

/// Murty's algorithm: the `k` lowest-cost assignments of [`hungarian`]'s problem (every row
/// assigned when rows <= columns, else every column), sorted by increasing cost, pairwise
/// distinct. Fewer than `k` are returned when fewer feasible assignments exist.
pub fn murty_k_best(cost: &DMatrix<f64>, k: usize) -> Result<Vec<Assignment>, AssocError> {
    check_costs(cost)?;
    let (n, m) = cost.shape();
    if n > m {
        let t = cost.transpose();
        return Ok(murty_k_best(&t, k)?
            .into_iter()
            .map(|a| {
                let mut row_to_col = vec![None; n];
                for (c, r) in a.row_to_col.iter().enumerate() {
                    if let Some(r) = r {
                        row_to_col[*r] = Some(c);
                    }
                }
                Assignment {
                    row_to_col,
                    cost: a.cost,
                }
            })
            .collect());
    }
    let mut out = Vec::new();
    if k == 0 {
        return Ok(out);
    }
    let solve = |forced: &[(usize, usize)], forbidden: &[(usize, usize)]| {
        let mut c = cost.clone();
        for &(r, col) in forced {
            for j in 0..m {
                if j != col {
                    c[(r, j)] = f64::INFINITY;
                }
            }
            for i in 0..n {
                if i != r {
                    c[(i, col)] = f64::INFINITY;
                }
            }
        }
        for &(r, col) in forbidden {
            c[(r, col)] = f64::INFINITY;
        }
        match solve_rows_le_cols(n, m, |i, j| c[(i, j)]) {
            Ok(sol) => Some(finish(cost, sol)),
            Err(_) => None,
        }
    };
    let mut heap = BinaryHeap::new();
    let mut seq = 0usize;
    match solve(&[], &[]) {
        Some(a) => heap.push(Node {
            cost: a.cost,
            seq,
            sol: a.row_to_col,
            forced: Vec::new(),
            forbidden: Vec::new(),
        }),
        None => return Ok(out),
    }
    while let Some(node) = heap.pop() {
        out.push(Assignment {
            row_to_col: node.sol.clone(),
            cost: node.cost,
        });
        if out.len() == k {
            break;
        }
        // Partition the node's space around its solution (rows not yet forced, in order).
        let mut forced = node.forced.clone();
        for r in 0..n {
            if node.forced.iter().any(|&(fr, _)| fr == r) {
                continue;
            }
            let Some(c) = node.sol[r] else { continue };
            let mut forbidden = node.forbidden.clone();
            forbidden.push((r, c));
            if let Some(a) = solve(&forced, &forbidden) {
                seq += 1;
                heap.push(Node {
                    cost: a.cost,
                    seq,
                    sol: a.row_to_col,
                    forced: forced.clone(),
                    forbidden,
                });
            }
            forced.push((r, c));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use quarry_testkit::brute::assignments;

    /// Cost matrices up to 4 x 4, one pair in five forbidden.
    fn mat() -> impl Strategy<Value = DMatrix<f64>> {
        quarry_testkit::strategies::matrix(
            1..5,
            1..5,
            prop_oneof![4 => 0.0f64..10.0, 1 => Just(f64::INFINITY)],
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        #[test]
        fn hungarian_equals_brute_force(c in mat()) {
            let all = assignments(&c);
            match hungarian(&c) {
                Ok(a) => {
                    prop_assert!(!all.is_empty());
                    prop_assert!((a.cost - all[0].0).abs() < 1e-9, "{} vs {}", a.cost, all[0].0);
                    // Uses no forbidden pair, and one column per row at most.
                    let mut seen = std::collections::HashSet::new();
                    for (r, col) in a.row_to_col.iter().enumerate() {
                        if let Some(j) = col {
                            prop_assert!(c[(r, *j)].is_finite());
                            prop_assert!(seen.insert(*j));
                        }
                    }
                }
                Err(AssocError::Infeasible(_)) => prop_assert!(all.is_empty()),
                Err(e) => prop_assert!(false, "unexpected {e}"),
            }
        }

        #[test]
        fn murty_sorted_distinct_and_complete(c in mat(), k in 1usize..30) {
            let all = assignments(&c);
            let best = murty_k_best(&c, k).unwrap();
            prop_assert_eq!(best.len(), k.min(all.len()));
            for w in best.windows(2) {
                prop_assert!(w[0].cost <= w[1].cost + 1e-12);
            }
            for (i, a) in best.iter().enumerate() {
                prop_assert!((a.cost - all[i].0).abs() < 1e-9);
                for b in &best[..i] {
                    prop_assert_ne!(&a.row_to_col, &b.row_to_col);
                }
            }
        }

        #[test]
        fn with_miss_is_optimal(c in mat(), miss in proptest::collection::vec(0.0f64..12.0, 4)) {
            let n = c.nrows();
            let a = hungarian_with_miss(&c, &miss[..n]).unwrap();
            let aug = augment_with_miss(&c, &miss[..n]).unwrap();
            let all = assignments(&aug);
            prop_assert!((a.cost - all[0].0).abs() < 1e-9);
        }
    }

    #[test]
    fn bad_inputs() {
        let c = DMatrix::from_row_slice(1, 2, &[f64::NAN, 1.0]);
        assert!(hungarian(&c).is_err());
        assert!(murty_k_best(&c, 2).is_err());
        let c = DMatrix::from_row_slice(2, 2, &[1.0, f64::INFINITY, 2.0, f64::INFINITY]);
        assert!(matches!(hungarian(&c), Err(AssocError::Infeasible(_))));
        assert!(murty_k_best(&c, 3).unwrap().is_empty());
        let e = DMatrix::<f64>::zeros(0, 3);
        assert_eq!(hungarian(&e).unwrap().row_to_col.len(), 0);
        assert!(hungarian_with_miss(&c, &[1.0]).is_err());
    }
}
