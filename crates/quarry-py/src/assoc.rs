//! Association bindings (quarry-assoc): the chi-square gate, optimal assignment (GNN,
//! Hungarian, Murty k-best) and the PDA / JPDA / JIPDA marginals of a log-likelihood matrix.

use crate::args::{self, Values, data, map_err, value_error};
use nalgebra::{DMatrix, SMatrix, SVector};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use quarry_assoc::assign::{self as qassign, Assignment};
use quarry_assoc::{Gnn, GnnCost, Jipda, Jpda, Method, Pda, Solver};
use quarry_core::{Association, Associator, Gaussian, LikelihoodMatrix, TrackPrior};

/// Builds an `(rows, cols)` numpy array from a row-major vector.
pub fn rows_to_py(
    py: Python<'_>,
    v: Vec<f64>,
    rows: usize,
    cols: usize,
) -> PyResult<Bound<'_, PyArray2<f64>>> {
    PyArray1::from_vec(py, v).reshape([rows, cols])
}

/// A nalgebra matrix as a row-major numpy array.
pub fn mat_to_py<'py>(py: Python<'py>, m: &DMatrix<f64>) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (r, c) = m.shape();
    rows_to_py(py, m.transpose().as_slice().to_vec(), r, c)
}

/// Reads a row-major `(rows, cols)` slice into a nalgebra matrix.
fn to_dmatrix(v: &[f64], rows: usize, cols: usize) -> DMatrix<f64> {
    DMatrix::from_row_slice(rows, cols, v)
}

/// The threshold γ on the squared Mahalanobis distance of a chi-square gate.
///
/// `γ = χ²_dim⁻¹(prob_gate)` (scipy's `chi2.ppf(prob_gate, dim)`).
#[pyfunction]
#[pyo3(signature = (prob_gate, dim))]
pub fn chi2_threshold(prob_gate: f64, dim: usize) -> PyResult<f64> {
    let dim = u32::try_from(dim).map_err(|_| value_error("dim", "is too large"))?;
    quarry_assoc::chi2::chi2_quantile(dim, prob_gate).map_err(map_err("chi2_threshold"))
}

/// Squared Mahalanobis distances and Gaussian log-likelihoods of one track against all
/// detections, for a fixed measurement dimension `Z`.
fn gate_rows<const Z: usize>(
    zhat: &[f64],
    s: &[f64],
    z: &[f64],
    n: usize,
    gamma: f64,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let m = z.len() / Z;
    let mut d2 = Vec::with_capacity(n * m);
    let mut ll = Vec::with_capacity(n * m);
    for i in 0..n {
        let mean = SVector::<f64, Z>::from_column_slice(&zhat[i * Z..(i + 1) * Z]);
        // row-major S[i] -> nalgebra (column-major): transpose of the column-major read
        let cov = SMatrix::<f64, Z, Z>::from_row_slice(&s[i * Z * Z..(i + 1) * Z * Z]);
        let g = Gaussian::try_new(mean, cov).map_err(|e| format!("S[{i}]: {e}"))?;
        for j in 0..m {
            let zj = SVector::<f64, Z>::from_column_slice(&z[j * Z..(j + 1) * Z]);
            let dd = g.mahalanobis2(&zj).map_err(|e| format!("S[{i}]: {e}"))?;
            d2.push(dd);
            ll.push(if dd <= gamma {
                g.log_pdf(&zj).map_err(|e| format!("S[{i}]: {e}"))?
            } else {
                f64::NEG_INFINITY
            });
        }
    }
    Ok((d2, ll))
}

/// Type of the gate result: (Mahalanobis², log-likelihood matrix).
type GateOut<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

/// Chi-square (ellipsoidal) gate of `n` predicted measurements against `m` detections.
///
/// `zhat` `(n, d)` predicted measurements, `S` `(n, d, d)` innovation covariances (symmetric
/// positive definite), `z` `(m, d)` detections, `d` in 1..=4. Returns `(d2, loglik)`, both
/// `(n, m)`: the squared Mahalanobis distances and `ln N(z_j; zhat_i, S_i)` inside the gate
/// (`d2 <= chi2.ppf(prob_gate, d)`), `-inf` outside — the input of `jpda` / `jipda` / `gnn`.
#[pyfunction]
#[pyo3(signature = (zhat, S, z, prob_gate = 0.99))]
#[allow(non_snake_case)]
pub fn chi2_gate<'py>(
    py: Python<'py>,
    zhat: &Bound<'py, PyAny>,
    S: &Bound<'py, PyAny>,
    z: &Bound<'py, PyAny>,
    prob_gate: f64,
) -> PyResult<GateOut<'py>> {
    let zh = args::array::<f64>(zhat, "zhat", "(n, d)", &[None, None], false, Values::Finite)?;
    let (n, d) = (zh.shape()[0], zh.shape()[1]);
    let sa = args::array::<f64>(
        S,
        "S",
        &format!("({n}, {d}, {d})"),
        &[Some(n), Some(d), Some(d)],
        false,
        Values::Finite,
    )?;
    let za = args::array::<f64>(
        z,
        "z",
        &format!("(m, {d})"),
        &[None, Some(d)],
        true,
        Values::Finite,
    )?;
    let m = za.shape()[0];
    args::check_cells("z", "the (n, m) output", n, m)?;
    let gamma = chi2_threshold(prob_gate, d)?;
    let (zh_s, s_s, z_s) = (data(&zh), data(&sa), data(&za));
    let out = py.detach(|| match d {
        1 => gate_rows::<1>(zh_s, s_s, z_s, n, gamma),
        2 => gate_rows::<2>(zh_s, s_s, z_s, n, gamma),
        3 => gate_rows::<3>(zh_s, s_s, z_s, n, gamma),
        4 => gate_rows::<4>(zh_s, s_s, z_s, n, gamma),
        _ => Err(format!(
            "measurement dimension {d} is not supported (1 to 4)"
        )),
    });
    let (d2, ll) = out.map_err(|e| value_error("chi2_gate", e))?;
    Ok((rows_to_py(py, d2, n, m)?, rows_to_py(py, ll, n, m)?))
}

/// Reads a log-likelihood matrix `(n, m)`: finite or `-inf` (not gated); `m` may be 0.
fn loglik_arg(ob: &Bound<'_, PyAny>) -> PyResult<LikelihoodMatrix> {
    let a = args::array::<f64>(
        ob,
        "loglik",
        "(n, m)",
        &[None, None],
        true,
        Values::FiniteOrNegInf,
    )?;
    let (n, m) = (a.shape()[0], a.shape()[1]);
    if n == 0 {
        return Err(value_error("loglik", "has no rows (no tracks)"));
    }
    LikelihoodMatrix::new(to_dmatrix(data(&a), n, m)).map_err(|e| value_error("loglik", e))
}

/// Per-track priors from optional `existence` / `detection` arrays of length `n`.
fn priors(
    n: usize,
    existence: Option<&Bound<'_, PyAny>>,
    detection: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<TrackPrior>> {
    let read = |ob: Option<&Bound<'_, PyAny>>, name: &str| -> PyResult<Option<Vec<f64>>> {
        ob.filter(|o| !o.is_none())
            .map(|o| {
                let a = args::array::<f64>(
                    o,
                    name,
                    &format!("({n},)"),
                    &[Some(n)],
                    false,
                    Values::Finite,
                )?;
                let v = data(&a).to_vec();
                if let Some(bad) = v.iter().find(|p| !(0.0..=1.0).contains(*p)) {
                    return Err(value_error(
                        name,
                        format!("{bad} is not a probability in [0, 1]"),
                    ));
                }
                Ok(v)
            })
            .transpose()
    };
    let e = read(existence, "existence")?;
    let d = read(detection, "detection")?;
    Ok((0..n)
        .map(|i| TrackPrior {
            existence: e.as_ref().map(|v| v[i]),
            detection: d.as_ref().map(|v| v[i]),
        })
        .collect())
}

/// The per-cluster solver from `method` ("auto", "exact", "lbp", "kbest") and `k`.
fn solver(method: &str, k: usize) -> PyResult<Solver> {
    let method = match method {
        "auto" => Method::Auto,
        "exact" => Method::Exact,
        "lbp" => Method::Lbp,
        "kbest" => {
            if k == 0 {
                return Err(value_error("k", "must be at least 1 for method=\"kbest\""));
            }
            Method::KBest { k }
        }
        other => {
            return Err(value_error(
                "method",
                format!("{other:?} is not one of \"auto\", \"exact\", \"lbp\", \"kbest\""),
            ));
        }
    };
    Ok(Solver {
        method,
        ..Solver::default()
    })
}

/// Runs an associator with the GIL released.
fn run(
    py: Python<'_>,
    call: &'static str,
    a: &(dyn Associator + Sync),
    lik: &LikelihoodMatrix,
    prior: &[TrackPrior],
) -> PyResult<Association> {
    py.detach(|| a.associate(lik, prior)).map_err(map_err(call))
}

/// Result of `pda` / `jpda`: (beta, log_normaliser).
type Marginals<'py> = (Bound<'py, PyArray2<f64>>, f64);

/// PDA marginals of each track alone (no exclusivity between tracks).
///
/// `loglik` `(n, m)` (`-inf` = not gated). Returns `(beta, log_normaliser)`, `beta` `(n, m + 1)`
/// with column 0 = missed detection; each row sums to 1.
#[pyfunction]
#[pyo3(signature = (loglik, pd, prob_gate, clutter_density, detection = None))]
pub fn pda<'py>(
    py: Python<'py>,
    loglik: &Bound<'py, PyAny>,
    pd: f64,
    prob_gate: f64,
    clutter_density: f64,
    detection: Option<&Bound<'py, PyAny>>,
) -> PyResult<Marginals<'py>> {
    let lik = loglik_arg(loglik)?;
    let prior = priors(lik.n_tracks(), None, detection)?;
    let a = Pda {
        pd,
        prob_gate,
        clutter_density,
    };
    let out = run(py, "pda", &a, &lik, &prior)?;
    Ok((mat_to_py(py, &out.beta)?, out.log_normaliser))
}

/// JPDA marginals (Bar-Shalom & Fortmann), exact per cluster by default.
///
/// `loglik` `(n, m)` (`-inf` = not gated), detection probability `pd`, gate probability
/// `prob_gate`, clutter density `clutter_density` (per unit measurement volume). `method`:
/// `"auto"` (exact while a cluster is small enough, else LBP), `"exact"`, `"lbp"`, or
/// `"kbest"` with `k` events per cluster. Optional per-track `detection` overrides `pd`.
/// Returns `(beta, log_normaliser)`, `beta` `(n, m + 1)`, column 0 = missed.
#[pyfunction]
#[pyo3(signature = (loglik, pd, prob_gate, clutter_density, method = "auto", k = 0, detection = None))]
#[allow(clippy::too_many_arguments)]
pub fn jpda<'py>(
    py: Python<'py>,
    loglik: &Bound<'py, PyAny>,
    pd: f64,
    prob_gate: f64,
    clutter_density: f64,
    method: &str,
    k: usize,
    detection: Option<&Bound<'py, PyAny>>,
) -> PyResult<Marginals<'py>> {
    let lik = loglik_arg(loglik)?;
    let prior = priors(lik.n_tracks(), None, detection)?;
    let a = Jpda::new(pd, prob_gate, clutter_density)
        .map_err(map_err("jpda"))?
        .with_solver(solver(method, k)?);
    let out = run(py, "jpda", &a, &lik, &prior)?;
    Ok((mat_to_py(py, &out.beta)?, out.log_normaliser))
}

/// Result of `jipda`: (beta, existence, log_normaliser).
type JipdaOut<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>, f64);

/// JIPDA (Musicki & Evans 2004): JPDA marginals conditioned on existence, and the posterior
/// existence probability of each track.
///
/// `existence` `(n,)` prior existence probabilities (multiplied by `survival`). Returns
/// `(beta, existence_posterior, log_normaliser)`.
#[pyfunction]
#[pyo3(signature = (loglik, existence, pd, prob_gate, clutter_density, survival = 1.0, method = "auto", k = 0, detection = None))]
#[allow(clippy::too_many_arguments)]
pub fn jipda<'py>(
    py: Python<'py>,
    loglik: &Bound<'py, PyAny>,
    existence: &Bound<'py, PyAny>,
    pd: f64,
    prob_gate: f64,
    clutter_density: f64,
    survival: f64,
    method: &str,
    k: usize,
    detection: Option<&Bound<'py, PyAny>>,
) -> PyResult<JipdaOut<'py>> {
    let lik = loglik_arg(loglik)?;
    let prior = priors(lik.n_tracks(), Some(existence), detection)?;
    let a = Jipda::new(pd, prob_gate, clutter_density)
        .map_err(map_err("jipda"))?
        .with_survival(survival)
        .with_solver(solver(method, k)?);
    let out = run(py, "jipda", &a, &lik, &prior)?;
    let ex = out.existence.unwrap_or_default();
    Ok((
        mat_to_py(py, &out.beta)?,
        PyArray1::from_vec(py, ex),
        out.log_normaliser,
    ))
}

/// `row_to_col` as int64 with -1 for "unassigned".
fn assignment_to_py<'py>(py: Python<'py>, a: &Assignment) -> Bound<'py, PyArray1<i64>> {
    PyArray1::from_vec(
        py,
        a.row_to_col
            .iter()
            .map(|c| c.map_or(-1, |j| i64::try_from(j).unwrap_or(-1)))
            .collect(),
    )
}

/// Result of an assignment: (row_to_col, cost).
type AssignOut<'py> = (Bound<'py, PyArray1<i64>>, f64);

/// Global nearest neighbour: the most likely one-to-one assignment of tracks to detections.
///
/// `cost="joint"` maximises the JPDA joint-event score (a track may stay unassigned at cost
/// `-ln(1 - pd prob_gate)`); `cost="max_cardinality"` assigns as many gated pairs as possible,
/// then minimises `-Σ loglik`. Returns `(row_to_col, cost)`: `row_to_col[i]` is the detection
/// of track `i` or -1.
#[pyfunction]
#[pyo3(signature = (loglik, pd, prob_gate, clutter_density, cost = "joint"))]
pub fn gnn<'py>(
    py: Python<'py>,
    loglik: &Bound<'py, PyAny>,
    pd: f64,
    prob_gate: f64,
    clutter_density: f64,
    cost: &str,
) -> PyResult<AssignOut<'py>> {
    let lik = loglik_arg(loglik)?;
    let (n, m) = (lik.n_tracks(), lik.n_meas());
    args::check_cells(
        "loglik",
        "the assignment problem with a miss column per track",
        n,
        m + n,
    )?;
    let mut g = Gnn::new(pd, prob_gate, clutter_density).map_err(map_err("gnn"))?;
    g.cost = match cost {
        "joint" => GnnCost::JointEvent,
        "max_cardinality" => GnnCost::MaxCardinality,
        other => {
            return Err(value_error(
                "cost",
                format!("{other:?} is not \"joint\" or \"max_cardinality\""),
            ));
        }
    };
    let prior = vec![TrackPrior::default(); lik.n_tracks()];
    let a = py
        .detach(|| g.solve(&lik, &prior))
        .map_err(map_err("gnn"))?;
    Ok((assignment_to_py(py, &a), a.cost))
}

/// Reads a cost matrix (finite or `+inf` = forbidden) and an optional miss cost per row.
fn cost_args(
    cost: &Bound<'_, PyAny>,
    miss_cost: Option<&Bound<'_, PyAny>>,
) -> PyResult<(DMatrix<f64>, Option<Vec<f64>>)> {
    let a = args::array::<f64>(
        cost,
        "cost",
        "(n, m)",
        &[None, None],
        true,
        Values::FiniteOrPosInf,
    )?;
    let (n, m) = (a.shape()[0], a.shape()[1]);
    let miss = miss_cost
        .filter(|o| !o.is_none())
        .map(|o| {
            args::array::<f64>(
                o,
                "miss_cost",
                &format!("({n},)"),
                &[Some(n)],
                true,
                Values::FiniteOrPosInf,
            )
            .map(|v| data(&v).to_vec())
        })
        .transpose()?;
    if miss.is_some() {
        args::check_cells(
            "cost",
            "the assignment problem with a miss column per row",
            n,
            m + n,
        )?;
    }
    Ok((to_dmatrix(data(&a), n, m), miss))
}

/// Minimum-cost assignment (Hungarian / shortest augmenting path) of a rectangular cost matrix
/// (`+inf` = forbidden pair). Every row is assigned when `n <= m` (every column otherwise); with
/// `miss_cost` `(n,)` a row may instead stay unassigned at that cost. Returns
/// `(row_to_col, total_cost)`, -1 = unassigned; `ValueError` when no assignment is feasible.
#[pyfunction]
#[pyo3(signature = (cost, miss_cost = None))]
pub fn assign<'py>(
    py: Python<'py>,
    cost: &Bound<'py, PyAny>,
    miss_cost: Option<&Bound<'py, PyAny>>,
) -> PyResult<AssignOut<'py>> {
    let (c, miss) = cost_args(cost, miss_cost)?;
    let a = py
        .detach(|| match &miss {
            Some(mc) => qassign::hungarian_with_miss(&c, mc),
            None => qassign::hungarian(&c),
        })
        .map_err(map_err("assign"))?;
    Ok((assignment_to_py(py, &a), a.cost))
}

/// Result of `murty_k_best`: (row_to_col `(k, n)`, costs `(k,)`).
type KBestOut<'py> = (Bound<'py, PyArray2<i64>>, Bound<'py, PyArray1<f64>>);

/// Murty's k best assignments of `assign`'s problem, by increasing cost (fewer when fewer
/// feasible assignments exist). Returns `(row_to_col (k', n) int64, costs (k',))`.
#[pyfunction]
#[pyo3(signature = (cost, k, miss_cost = None))]
pub fn murty_k_best<'py>(
    py: Python<'py>,
    cost: &Bound<'py, PyAny>,
    k: usize,
    miss_cost: Option<&Bound<'py, PyAny>>,
) -> PyResult<KBestOut<'py>> {
    let (c, miss) = cost_args(cost, miss_cost)?;
    if k == 0 {
        return Err(value_error("k", "must be at least 1"));
    }
    let best = py
        .detach(|| match &miss {
            Some(mc) => qassign::murty_k_best_with_miss(&c, mc, k),
            None => qassign::murty_k_best(&c, k),
        })
        .map_err(map_err("murty_k_best"))?;
    let n = c.nrows();
    let rows: Vec<i64> = best
        .iter()
        .flat_map(|a| {
            a.row_to_col
                .iter()
                .map(|c| c.map_or(-1, |j| i64::try_from(j).unwrap_or(-1)))
        })
        .collect();
    let costs: Vec<f64> = best.iter().map(|a| a.cost).collect();
    Ok((
        PyArray1::from_vec(py, rows).reshape([best.len(), n])?,
        PyArray1::from_vec(py, costs),
    ))
}

/// Registers the association functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(chi2_threshold, m)?)?;
    m.add_function(wrap_pyfunction!(chi2_gate, m)?)?;
    m.add_function(wrap_pyfunction!(pda, m)?)?;
    m.add_function(wrap_pyfunction!(jpda, m)?)?;
    m.add_function(wrap_pyfunction!(jipda, m)?)?;
    m.add_function(wrap_pyfunction!(gnn, m)?)?;
    m.add_function(wrap_pyfunction!(assign, m)?)?;
    m.add_function(wrap_pyfunction!(murty_k_best, m)?)?;
    Ok(())
}
