//! Brute-force reference implementations: exhaustive enumeration and linear scans.

use nalgebra::DMatrix;
use quarry_core::Point2;

/// Every assignment of `min(n, m)` (row, column) pairs of the `n x m` matrix `cost` whose total
/// is finite, as `(total, row_to_col)`, cheapest first (stable among equal totals).
///
/// When `n > m` some rows stay unassigned (`None`); an infinite entry forbids its pair.
pub fn assignments(cost: &DMatrix<f64>) -> Vec<(f64, Vec<Option<usize>>)> {
    fn rec(
        i: usize,
        cost: &DMatrix<f64>,
        cur: &mut Vec<Option<usize>>,
        used: &mut Vec<bool>,
        out: &mut Vec<(f64, Vec<Option<usize>>)>,
    ) {
        let (n, m) = cost.shape();
        if i == n {
            let k = cur.iter().filter(|c| c.is_some()).count();
            if k == n.min(m) {
                let c: f64 = cur
                    .iter()
                    .enumerate()
                    .filter_map(|(r, c)| c.map(|j| cost[(r, j)]))
                    .sum();
                if c.is_finite() {
                    out.push((c, cur.clone()));
                }
            }
            return;
        }
        if n > m {
            cur[i] = None;
            rec(i + 1, cost, cur, used, out);
        }
        for j in 0..m {
            if !used[j] {
                used[j] = true;
                cur[i] = Some(j);
                rec(i + 1, cost, cur, used, out);
                used[j] = false;
                cur[i] = None;
            }
        }
    }
    let (n, m) = cost.shape();
    let mut out = Vec::new();
    rec(0, cost, &mut vec![None; n], &mut vec![false; m], &mut out);
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// The optimal linear-sum-assignment cost of the row-major `n_rows x n_cols` matrix `cost`
/// (`min(n_rows, n_cols)` pairs): the cheapest of [`assignments`], `inf` when none is finite.
pub fn lsap_cost(cost: &[f64], n_rows: usize, n_cols: usize) -> f64 {
    assignments(&DMatrix::from_row_slice(n_rows, n_cols, cost))
        .first()
        .map_or(f64::INFINITY, |a| a.0)
}

/// Calls `f` with every feasible JPDA joint event of the score matrix `l` (`n x (m + 1)`, column
/// 0 the missed detection): `event[i]` is track `i`'s column, `0` (missed, always allowed) or a
/// detection `j >= 1` with `l[(i, j)] > 0` that no other track of the event takes.
///
/// Events come depth first, track 0 outermost, missed before detections in column order.
pub fn joint_events(l: &DMatrix<f64>, mut f: impl FnMut(&[usize])) {
    fn rec(
        i: usize,
        l: &DMatrix<f64>,
        a: &mut Vec<usize>,
        used: &mut Vec<bool>,
        f: &mut dyn FnMut(&[usize]),
    ) {
        let (n, m1) = l.shape();
        if i == n {
            f(a);
            return;
        }
        a[i] = 0;
        rec(i + 1, l, a, used, f);
        for j in 1..m1 {
            if !used[j] && l[(i, j)] > 0.0 {
                used[j] = true;
                a[i] = j;
                rec(i + 1, l, a, used, f);
                used[j] = false;
            }
        }
    }
    let (n, m1) = l.shape();
    rec(0, l, &mut vec![0; n], &mut vec![false; m1], &mut f);
}

/// Exact JPDA by enumeration: the marginals `β̃ = Σ_events w · 1[i → j] / c` and the normaliser
/// `c = Σ_events w`, with `w = Π_i l[(i, event[i])]`, over [`joint_events`] of `l`.
///
/// When every event weighs zero, `c = 0` and `β̃` is NaN.
pub fn jpda_marginals(l: &DMatrix<f64>) -> (DMatrix<f64>, f64) {
    let (n, m1) = l.shape();
    let mut beta = DMatrix::zeros(n, m1);
    let mut c = 0.0;
    joint_events(l, |a| {
        let w: f64 = (0..n).map(|k| l[(k, a[k])]).product();
        c += w;
        for k in 0..n {
            beta[(k, a[k])] += w;
        }
    });
    (beta / c, c)
}

/// The log-weight `Σ_i ln l[(i, event[i])]` of the best joint event (the GNN optimum), over the
/// [`joint_events`] of `l` in which every missed track has `l[(i, 0)] > 0`; `-inf` when there is
/// none.
pub fn best_event_log_weight(l: &DMatrix<f64>) -> f64 {
    let mut best = f64::NEG_INFINITY;
    joint_events(l, |a| {
        if a.iter()
            .enumerate()
            .all(|(i, &j)| j != 0 || l[(i, 0)] > 0.0)
        {
            let lw = a
                .iter()
                .enumerate()
                .fold(0.0, |lw, (i, &j)| lw + l[(i, j)].ln());
            best = best.max(lw);
        }
    });
    best
}

/// The indices `i` (ascending) with `keep(i)` and `|points[i] - q|² <= radius²`.
pub fn within(
    points: &[Point2],
    q: &Point2,
    radius: f64,
    keep: impl Fn(usize) -> bool,
) -> Vec<usize> {
    (0..points.len())
        .filter(|&i| keep(i) && (points[i] - q).norm_squared() <= radius * radius)
        .collect()
}

/// The distance from `q` to the nearest of the `points[i]` with `keep(i)`; `inf` when none is
/// kept.
pub fn nearest_distance(points: &[Point2], q: &Point2, keep: impl Fn(usize) -> bool) -> f64 {
    (0..points.len())
        .filter(|&i| keep(i))
        .map(|i| (points[i] - q).norm())
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assignments_of_a_small_matrix() {
        let c = DMatrix::from_row_slice(2, 3, &[1.0, 2.0, f64::INFINITY, 3.0, 1.0, 5.0]);
        let all = assignments(&c);
        // 3 * 2 injective maps minus the two that use the forbidden (0, 2) pair
        assert_eq!(all.len(), 4);
        assert_eq!(all[0], (2.0, vec![Some(0), Some(1)]));
        assert_eq!(
            lsap_cost(&[1.0, 2.0, f64::INFINITY, 3.0, 1.0, 5.0], 2, 3),
            2.0
        );
        // the transposed problem leaves one row out
        assert_eq!(assignments(&c.transpose())[0].0, 2.0);
        assert_eq!(lsap_cost(&[f64::INFINITY], 1, 1), f64::INFINITY);
    }

    #[test]
    fn jpda_of_one_track_and_one_detection() {
        // missed 0.25, detected 0.75 (both events feasible)
        let l = DMatrix::from_row_slice(1, 2, &[0.25, 0.75]);
        let mut n = 0;
        joint_events(&l, |_| n += 1);
        assert_eq!(n, 2);
        let (beta, c) = jpda_marginals(&l);
        assert_eq!(c, 1.0);
        assert_eq!(beta[(0, 1)], 0.75);
        assert_eq!(best_event_log_weight(&l), 0.75f64.ln());
        // a missed detection of weight 0 is not an event for the GNN optimum
        let l = DMatrix::from_row_slice(1, 2, &[0.0, 0.0]);
        assert_eq!(best_event_log_weight(&l), f64::NEG_INFINITY);
    }

    #[test]
    fn linear_scans() {
        let p = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(3.0, 0.0),
        ];
        let q = Point2::new(0.9, 0.0);
        assert_eq!(within(&p, &q, 1.0, |_| true), vec![0, 1]);
        assert_eq!(within(&p, &q, 1.0, |i| i != 1), vec![0]);
        assert!((nearest_distance(&p, &q, |_| true) - 0.1).abs() < 1e-12);
        assert_eq!(nearest_distance(&p, &q, |_| false), f64::INFINITY);
    }
}
