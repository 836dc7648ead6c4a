//! Optimal assignment (the linear sum assignment problem).
//!
//! [`linear_sum_assignment`] is a line-by-line port of SciPy's `rectangular_lsap.cpp` (Crouse's
//! shortest augmenting path variant of Jonker-Volgenant, SciPy >= 1.4). The port is exact down to
//! the tie-breaking rules and the order of floating-point operations, which is what lets the MOT
//! metrics in this crate reproduce py-motmetrics and TrackEval to the last digit: both call
//! SciPy, and when two assignments have equal cost the one SciPy picks decides which object is
//! matched to which track. The `tests/fixtures/lsap_ties.json` fixture checks the port against
//! SciPy on tie-heavy integer matrices.
//!
//! [`hungarian_match`] is the gated form trackers and metrics use: pairs whose cost exceeds a
//! limit (or is NaN) are never returned.

use quarry_core::CoreError;

use crate::EvalError;

/// Solves `min sum_k cost[rows[k]][cols[k]]` over one-to-one assignments of
/// `min(n_rows, n_cols)` pairs.
///
/// `cost` is row-major with `n_rows * n_cols` finite entries. Returns the pairs `(row, col)`
/// sorted by row, exactly as `scipy.optimize.linear_sum_assignment` does (including which of
/// several optimal assignments is returned).
///
/// ```
/// use quarry_eval::lsap::linear_sum_assignment;
/// let cost = [4.0, 1.0, 3.0,
///             2.0, 0.0, 5.0,
///             3.0, 2.0, 2.0];
/// let pairs = linear_sum_assignment(&cost, 3, 3)?;
/// assert_eq!(pairs, vec![(0, 1), (1, 0), (2, 2)]);
/// # Ok::<(), quarry_eval::EvalError>(())
/// ```
pub fn linear_sum_assignment(
    cost: &[f64],
    n_rows: usize,
    n_cols: usize,
) -> Result<Vec<(usize, usize)>, EvalError> {
    quarry_core::ensure_len(cost.len(), n_rows * n_cols, "cost matrix")?;
    quarry_core::ensure_finite(cost, "cost matrix")?;
    if n_rows == 0 || n_cols == 0 {
        return Ok(Vec::new());
    }
    let transpose = n_cols < n_rows;
    let (nr, nc) = if transpose {
        (n_cols, n_rows)
    } else {
        (n_rows, n_cols)
    };
    let transposed;
    let c: &[f64] = if transpose {
        let mut t = vec![0.0; cost.len()];
        for i in 0..n_rows {
            for j in 0..n_cols {
                t[j * n_rows + i] = cost[i * n_cols + j];
            }
        }
        transposed = t;
        &transposed
    } else {
        cost
    };

    let mut u = vec![0.0_f64; nr];
    let mut v = vec![0.0_f64; nc];
    let mut shortest = vec![f64::INFINITY; nc];
    let mut path = vec![usize::MAX; nc];
    let mut col4row = vec![usize::MAX; nr];
    let mut row4col = vec![usize::MAX; nc];
    let mut sr = vec![false; nr];
    let mut sc = vec![false; nc];
    let mut remaining = vec![0usize; nc];

    for cur_row in 0..nr {
        // --- augmenting_path ---
        let mut min_val = 0.0_f64;
        let mut num_remaining = nc;
        for (it, r) in remaining.iter_mut().enumerate() {
            *r = nc - it - 1;
        }
        sr.fill(false);
        sc.fill(false);
        shortest.fill(f64::INFINITY);
        let mut i = cur_row;
        let sink = loop {
            let mut index = usize::MAX;
            let mut lowest = f64::INFINITY;
            sr[i] = true;
            for (it, &j) in remaining.iter().enumerate().take(num_remaining) {
                let r = min_val + c[i * nc + j] - u[i] - v[j];
                if r < shortest[j] {
                    path[j] = i;
                    shortest[j] = r;
                }
                if shortest[j] < lowest || (shortest[j] == lowest && row4col[j] == usize::MAX) {
                    lowest = shortest[j];
                    index = it;
                }
            }
            min_val = lowest;
            if index == usize::MAX || min_val == f64::INFINITY {
                return Err(CoreError::numerical(
                    "linear_sum_assignment",
                    "no feasible assignment (cost overflowed to infinity)",
                )
                .into());
            }
            let j = remaining[index];
            sc[j] = true;
            num_remaining -= 1;
            remaining[index] = remaining[num_remaining];
            if row4col[j] == usize::MAX {
                break j;
            }
            i = row4col[j];
        };

        // --- update dual variables ---
        u[cur_row] += min_val;
        for i in 0..nr {
            if sr[i] && i != cur_row {
                u[i] += min_val - shortest[col4row[i]];
            }
        }
        for j in 0..nc {
            if sc[j] {
                v[j] -= min_val - shortest[j];
            }
        }

        // --- augment ---
        let mut j = sink;
        loop {
            let i = path[j];
            row4col[j] = i;
            std::mem::swap(&mut col4row[i], &mut j);
            if i == cur_row {
                break;
            }
        }
    }

    let mut pairs: Vec<(usize, usize)> = if transpose {
        // rows of the transposed problem are the original columns
        col4row.iter().enumerate().map(|(c, &r)| (r, c)).collect()
    } else {
        col4row.iter().enumerate().map(|(r, &c)| (r, c)).collect()
    };
    pairs.sort_unstable();
    Ok(pairs)
}

/// Gated optimal assignment: minimises the total cost over pairs whose cost is finite and at
/// most `max_cost`, and returns only such pairs (sorted by row).
///
/// Entries that are NaN or `+inf` mark pairs that may not be matched. The forbidden pairs get
/// py-motmetrics' "expensive edge" cost `2 r c + 1` (`r = min(n_rows, n_cols)`, `c` = the
/// largest allowed |cost| + 1), large enough that an optimal assignment never trades an allowed
/// pair for a forbidden one, and are then dropped from the answer. This is exactly what
/// py-motmetrics does before calling SciPy, so the same pairs come out.
///
/// ```
/// use quarry_eval::lsap::hungarian_match;
/// // distances between 2 ground-truth points and 3 tracks; 0.5 m gate
/// let d = [0.1, 0.9, f64::NAN,
///          0.7, 0.2, 0.3];
/// assert_eq!(hungarian_match(&d, 2, 3, 0.5)?, vec![(0, 0), (1, 1)]);
/// # Ok::<(), quarry_eval::EvalError>(())
/// ```
pub fn hungarian_match(
    cost: &[f64],
    n_rows: usize,
    n_cols: usize,
    max_cost: f64,
) -> Result<Vec<(usize, usize)>, EvalError> {
    quarry_core::ensure_len(cost.len(), n_rows * n_cols, "cost matrix")?;
    if max_cost.is_nan() {
        return Err(CoreError::invalid("max_cost", "must not be NaN").into());
    }
    if cost.contains(&f64::NEG_INFINITY) {
        return Err(CoreError::NonFinite {
            what: "cost matrix",
        }
        .into());
    }
    let gated: Vec<f64> = cost
        .iter()
        .map(|&x| {
            if x <= max_cost && x.is_finite() {
                x
            } else {
                f64::NAN
            }
        })
        .collect();
    assign_with_forbidden(&gated, n_rows, n_cols)
}

/// Optimal assignment where NaN marks a forbidden pair (py-motmetrics' `lsa_solve_scipy`).
pub(crate) fn assign_with_forbidden(
    cost: &[f64],
    n_rows: usize,
    n_cols: usize,
) -> Result<Vec<(usize, usize)>, EvalError> {
    if n_rows == 0 || n_cols == 0 {
        return Ok(Vec::new());
    }
    let max_abs = cost
        .iter()
        .filter(|x| x.is_finite())
        .fold(None, |m: Option<f64>, &x| {
            Some(m.map_or(x.abs(), |m| m.max(x.abs())))
        });
    let Some(max_abs) = max_abs else {
        return Ok(Vec::new());
    };
    let r = n_rows.min(n_cols) as f64;
    let c = max_abs + 1.0;
    let large = 2.0 * r * c + 1.0;
    let finite: Vec<f64> = cost
        .iter()
        .map(|&x| if x.is_finite() { x } else { large })
        .collect();
    let pairs = linear_sum_assignment(&finite, n_rows, n_cols)?;
    Ok(pairs
        .into_iter()
        .filter(|&(i, j)| cost[i * n_cols + j].is_finite())
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use quarry_testkit::brute;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn optimal_against_brute_force(nr in 1usize..6, nc in 1usize..6, seed in proptest::collection::vec(0.0f64..10.0, 36)) {
            let cost: Vec<f64> = seed[..nr * nc].to_vec();
            let pairs = linear_sum_assignment(&cost, nr, nc).unwrap();
            prop_assert_eq!(pairs.len(), nr.min(nc));
            let mut rows: Vec<usize> = pairs.iter().map(|p| p.0).collect();
            let mut cols: Vec<usize> = pairs.iter().map(|p| p.1).collect();
            rows.dedup(); cols.sort_unstable(); cols.dedup();
            prop_assert_eq!(rows.len(), pairs.len());
            prop_assert_eq!(cols.len(), pairs.len());
            let total: f64 = pairs.iter().map(|&(i, j)| cost[i * nc + j]).sum();
            prop_assert!((total - brute::lsap_cost(&cost, nr, nc)).abs() < 1e-9);
        }
    }

    #[test]
    fn constant_matrix_gives_identity_like_scipy() {
        let pairs = linear_sum_assignment(&[1.0; 9], 3, 3).unwrap();
        assert_eq!(pairs, vec![(0, 0), (1, 1), (2, 2)]);
    }

    #[test]
    fn rejects_bad_input() {
        assert!(linear_sum_assignment(&[1.0, f64::NAN], 1, 2).is_err());
        assert!(linear_sum_assignment(&[1.0, 2.0, 3.0], 2, 2).is_err());
        assert!(hungarian_match(&[1.0], 1, 1, f64::NAN).is_err());
        assert_eq!(linear_sum_assignment(&[], 0, 3).unwrap(), vec![]);
    }

    #[test]
    fn gate_drops_forbidden_pairs() {
        let d = [0.6, 0.7, 0.8, 0.9];
        assert!(hungarian_match(&d, 2, 2, 0.5).unwrap().is_empty());
        // the gate must not change which allowed pair is chosen
        let d = [0.1, 0.2, f64::INFINITY, 0.05];
        assert_eq!(
            hungarian_match(&d, 2, 2, 1.0).unwrap(),
            vec![(0, 0), (1, 1)]
        );
    }
}
