//! Metric bindings (quarry-eval): CLEAR MOT, IDF1 and HOTA on MOTChallenge-style arrays or
//! files, OSPA and GOSPA on point sets.

use crate::args::{self, Values, data, map_err, value_error};
use numpy::{PyArray1, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use quarry_eval::mot::hota_alphas;
use quarry_eval::motchallenge::{self, GtStyle};
use quarry_eval::{Euclidean, Frame, Iou, MotEvaluation, MotSummary, Similarity};
use std::collections::BTreeMap;

/// An integer stored in a float column (frame number or id).
fn int_cell(name: &str, col: &str, row: usize, v: f64) -> PyResult<i64> {
    if v.fract() != 0.0 || v.abs() > 9.0e15 {
        return Err(value_error(
            name,
            format!("row {row}: {col} {v} is not an integer"),
        ));
    }
    #[allow(clippy::cast_possible_truncation)]
    Ok(v as i64)
}

/// Rows grouped by frame number: frame -> [(id, values)].
type ByFrame<const K: usize> = BTreeMap<i64, Vec<(i64, [f64; K])>>;

/// Groups `(N, 2 + K)` rows `frame, id, v_1..v_K` by frame: frame number -> [(id, values)].
fn group<const K: usize>(name: &str, rows: &[f64]) -> PyResult<ByFrame<K>> {
    let mut out: ByFrame<K> = BTreeMap::new();
    for (r, row) in rows.chunks_exact(2 + K).enumerate() {
        let frame = int_cell(name, "frame", r, row[0])?;
        let id = int_cell(name, "id", r, row[1])?;
        let mut v = [0.0; K];
        v.copy_from_slice(&row[2..]);
        out.entry(frame).or_default().push((id, v));
    }
    Ok(out)
}

/// Frames over the union of frame numbers of both sides, in increasing order.
fn frames<const K: usize>(gt: &ByFrame<K>, hyp: &ByFrame<K>) -> Vec<Frame<[f64; K]>> {
    let mut keys: Vec<i64> = gt.keys().chain(hyp.keys()).copied().collect();
    keys.sort_unstable();
    keys.dedup();
    keys.iter()
        .map(|k| Frame {
            gt: gt.get(k).cloned().unwrap_or_default(),
            hyp: hyp.get(k).cloned().unwrap_or_default(),
        })
        .collect()
}

/// Most `distinct ground-truth ids × distinct hypothesis ids` accepted: IDF1 and HOTA keep dense
/// matrices of that many cells (as py-motmetrics and TrackEval do), so a sequence beyond it would
/// exhaust memory and abort the interpreter instead of raising.
pub const MAX_ID_PAIRS: usize = 1 << 27;

/// Checks the id product of a sequence against [`MAX_ID_PAIRS`].
fn check_id_pairs<T>(frames: &[Frame<T>]) -> Result<(), String> {
    let count = |side: &dyn Fn(&Frame<T>) -> Vec<i64>| {
        let mut ids: Vec<i64> = frames.iter().flat_map(side).collect();
        ids.sort_unstable();
        ids.dedup();
        ids.len()
    };
    let g = count(&|f| f.gt.iter().map(|p| p.0).collect());
    let h = count(&|f| f.hyp.iter().map(|p| p.0).collect());
    if g.saturating_mul(h) > MAX_ID_PAIRS {
        return Err(format!(
            "{g} ground-truth ids × {h} hypothesis ids exceed the {MAX_ID_PAIRS} cells of the \
             dense IDF1 / HOTA matrices"
        ));
    }
    Ok(())
}

/// Compares the sequence and scores all three families with the GIL released.
fn score<const K: usize, S: Similarity<[f64; K]> + Sync>(
    py: Python<'_>,
    gt: &[f64],
    hyp: &[f64],
    sim: &S,
) -> PyResult<MotSummary> {
    let g = group::<K>("gt", gt)?;
    let h = group::<K>("hyp", hyp)?;
    py.detach(|| {
        let f = frames(&g, &h);
        check_id_pairs(&f)?;
        MotEvaluation::new(&f, sim)
            .and_then(|e| e.summary())
            .map_err(|e| e.to_string())
    })
    .map_err(map_err("mot_metrics"))
}

/// The summary as a dict with py-motmetrics' names for CLEAR / identity and TrackEval's
/// (lower case) for HOTA; ratios without a denominator are NaN, as in py-motmetrics.
fn summary_dict<'py>(py: Python<'py>, s: &MotSummary) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let c = &s.clear;
    let nan = |v: Option<f64>| v.unwrap_or(f64::NAN);
    d.set_item("mota", nan(c.mota()))?;
    d.set_item("moda", nan(c.moda()))?;
    d.set_item("motp", nan(c.motp()))?;
    d.set_item("recall", nan(c.recall()))?;
    d.set_item("precision", nan(c.precision()))?;
    d.set_item("num_frames", c.num_frames)?;
    d.set_item("num_objects", c.num_objects)?;
    d.set_item("num_predictions", c.num_predictions)?;
    d.set_item("num_unique_objects", c.num_unique_objects)?;
    d.set_item("num_matches", c.num_matches)?;
    d.set_item("num_switches", c.num_switches)?;
    d.set_item("num_false_positives", c.num_false_positives)?;
    d.set_item("num_misses", c.num_misses)?;
    d.set_item("num_fragmentations", c.num_fragmentations)?;
    d.set_item("num_transfer", c.num_transfer)?;
    d.set_item("num_ascend", c.num_ascend)?;
    d.set_item("num_migrate", c.num_migrate)?;
    d.set_item("mostly_tracked", c.mostly_tracked)?;
    d.set_item("partially_tracked", c.partially_tracked)?;
    d.set_item("mostly_lost", c.mostly_lost)?;
    let i = &s.identity;
    d.set_item("idf1", nan(i.idf1()))?;
    d.set_item("idp", nan(i.idp()))?;
    d.set_item("idr", nan(i.idr()))?;
    d.set_item("idtp", i.idtp)?;
    d.set_item("idfp", i.idfp)?;
    d.set_item("idfn", i.idfn)?;
    let h = &s.hota;
    d.set_item("hota", h.hota_mean())?;
    d.set_item("deta", h.deta_mean())?;
    d.set_item("assa", h.assa_mean())?;
    d.set_item("loca", h.loca_mean())?;
    d.set_item("detre", h.detre_mean())?;
    d.set_item("detpr", h.detpr_mean())?;
    d.set_item("assre", h.assre_mean())?;
    d.set_item("asspr", h.asspr_mean())?;
    d.set_item("hota_alpha", PyArray1::from_slice(py, &hota_alphas()))?;
    d.set_item("hota_per_alpha", PyArray1::from_slice(py, &h.hota))?;
    d.set_item("deta_per_alpha", PyArray1::from_slice(py, &h.deta))?;
    d.set_item("assa_per_alpha", PyArray1::from_slice(py, &h.assa))?;
    Ok(d)
}

/// CLEAR MOT (py-motmetrics' conventions), IDF1 / IDP / IDR and HOTA (TrackEval's) of a
/// sequence given as arrays of rows.
///
/// `similarity="iou"`: `gt` and `hyp` are `(N, 6)` float64 rows `frame, id, left, top, width,
/// height` (the first six MOTChallenge columns); a match needs IoU >= `threshold` (default 0.5),
/// MOTP is the mean `1 - IoU`, HOTA's similarity is the IoU.
/// `similarity="euclidean"`: rows `frame, id, x, y` (`(N, 4)`) or `frame, id, x, y, z`
/// (`(N, 5)`); a match needs distance <= `threshold`, MOTP is the mean distance, HOTA's
/// similarity is `max(0, 1 - d / zero_at)` (`zero_at` defaults to `2 threshold`).
///
/// Frames are the union of the frame numbers of both arrays. Returns a dict (`mota`, `motp`,
/// `idf1`, `hota`, `deta`, `assa`, counts with py-motmetrics' names, per-alpha HOTA arrays).
#[pyfunction]
#[pyo3(signature = (gt, hyp, similarity = "iou", threshold = None, zero_at = None))]
pub fn mot_metrics<'py>(
    py: Python<'py>,
    gt: &Bound<'py, PyAny>,
    hyp: &Bound<'py, PyAny>,
    similarity: &str,
    threshold: Option<f64>,
    zero_at: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let summary = match similarity {
        "iou" => {
            let expected = "(N, 6) rows frame, id, left, top, width, height";
            let g = args::array::<f64>(gt, "gt", expected, &[None, Some(6)], true, Values::Finite)?;
            let h =
                args::array::<f64>(hyp, "hyp", expected, &[None, Some(6)], true, Values::Finite)?;
            if zero_at.is_some() {
                return Err(value_error(
                    "zero_at",
                    "only applies to similarity=\"euclidean\"",
                ));
            }
            let sim =
                Iou::new(threshold.unwrap_or(0.5)).map_err(|e| value_error("threshold", e))?;
            score::<4, _>(py, data(&g), data(&h), &sim)?
        }
        "euclidean" => {
            let th = threshold.ok_or_else(|| {
                value_error("threshold", "is required for similarity=\"euclidean\"")
            })?;
            let sim = match zero_at {
                Some(z) => Euclidean::with_zero_at(th, z),
                None => Euclidean::new(th),
            }
            .map_err(|e| value_error("threshold", e))?;
            let expected = "(N, 4) rows frame, id, x, y or (N, 5) rows frame, id, x, y, z";
            let g = args::array::<f64>(gt, "gt", expected, &[None, None], true, Values::Finite)?;
            let cols = g.shape()[1];
            if cols != 4 && cols != 5 {
                return Err(value_error(
                    "gt",
                    format!("expected {expected}, got {cols} columns"),
                ));
            }
            let h = args::array::<f64>(
                hyp,
                "hyp",
                expected,
                &[None, Some(cols)],
                true,
                Values::Finite,
            )?;
            if cols == 4 {
                score::<2, _>(py, data(&g), data(&h), &sim)?
            } else {
                score::<3, _>(py, data(&g), data(&h), &sim)?
            }
        }
        other => {
            return Err(value_error(
                "similarity",
                format!("{other:?} is not \"iou\" or \"euclidean\""),
            ));
        }
    };
    summary_dict(py, &summary)
}

/// CLEAR MOT, IDF1 and HOTA of a MOTChallenge results file against a ground-truth file
/// (box IoU >= `threshold`).
///
/// Ground truth rows with flag 0 or a distractor class are ignored the MOTChallenge way
/// (results matched to them are dropped). `gt_style`: `"auto"` (9 columns = MOT16+),
/// `"mot15"` or `"mot16"`. Returns the same dict as `mot_metrics`.
#[pyfunction]
#[pyo3(signature = (gt_path, res_path, threshold = 0.5, gt_style = "auto"))]
#[allow(clippy::needless_pass_by_value)] // pyo3 extracts owned paths
pub fn mot_metrics_files<'py>(
    py: Python<'py>,
    gt_path: std::path::PathBuf,
    res_path: std::path::PathBuf,
    threshold: f64,
    gt_style: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let style = match gt_style {
        "auto" => GtStyle::Auto,
        "mot15" => GtStyle::Mot15,
        "mot16" => GtStyle::Mot16,
        other => {
            return Err(value_error(
                "gt_style",
                format!("{other:?} is not \"auto\", \"mot15\" or \"mot16\""),
            ));
        }
    };
    let sim = Iou::new(threshold).map_err(|e| value_error("threshold", e))?;
    let summary = py
        .detach(|| {
            let gt = motchallenge::read_gt_file(&gt_path, style)?;
            let res = motchallenge::read_results_file(&res_path)?;
            let f = motchallenge::to_frames(&gt, &res, threshold)?;
            check_id_pairs(&f).map_err(|e| {
                quarry_eval::EvalError::from(quarry_core::CoreError::invalid("ids", e))
            })?;
            MotEvaluation::new(&f, &sim)?.summary()
        })
        .map_err(map_err("mot_metrics_files"))?;
    summary_dict(py, &summary)
}

/// Reads two point sets `(m, d)` and `(n, d)` (either may be empty) for OSPA / GOSPA.
fn point_sets(x: &Bound<'_, PyAny>, y: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Vec<f64>, usize)> {
    let xa = args::array::<f64>(x, "x", "(m, d)", &[None, None], true, Values::Finite)?;
    let d = xa.shape()[1];
    let ya = args::array::<f64>(
        y,
        "y",
        &format!("(n, {d})"),
        &[None, Some(d)],
        true,
        Values::Finite,
    )?;
    if d == 0 || d > 4 {
        return Err(value_error(
            "x",
            format!("point dimension {d} is not supported (1 to 4)"),
        ));
    }
    args::check_cells(
        "y",
        "the (m, n) distance matrix",
        xa.shape()[0],
        ya.shape()[0],
    )?;
    Ok((data(&xa).to_vec(), data(&ya).to_vec(), d))
}

/// Reinterprets a flat slice as fixed-size points.
fn points<const D: usize>(v: &[f64]) -> Vec<[f64; D]> {
    v.chunks_exact(D)
        .map(|c| {
            let mut p = [0.0; D];
            p.copy_from_slice(c);
            p
        })
        .collect()
}

/// Runs `f::<D>` for the point dimension `d` (1..=4).
macro_rules! by_dim {
    ($d:expr, $f:ident, $x:expr, $y:expr, $($rest:expr),*) => {
        match $d {
            1 => $f(&points::<1>($x), &points::<1>($y), $($rest),*),
            2 => $f(&points::<2>($x), &points::<2>($y), $($rest),*),
            3 => $f(&points::<3>($x), &points::<3>($y), $($rest),*),
            _ => $f(&points::<4>($x), &points::<4>($y), $($rest),*),
        }
    };
}

/// OSPA distance of order `p` with cut-off `c` between point sets `x` `(m, d)` and `y`
/// `(n, d)` (Schuhmacher, Vo & Vo 2008); 0 when both are empty.
#[pyfunction]
#[pyo3(signature = (x, y, c, p = 1.0))]
pub fn ospa(x: &Bound<'_, PyAny>, y: &Bound<'_, PyAny>, c: f64, p: f64) -> PyResult<f64> {
    let (xs, ys, d) = point_sets(x, y)?;
    use quarry_eval::ospa::ospa as f;
    by_dim!(d, f, &xs, &ys, p, c).map_err(map_err("ospa"))
}

/// GOSPA (alpha = 2) of order `p` with cut-off `c` between the truth `x` and the estimates `y`.
///
/// Returns a dict: `distance`, `localisation` (sum of `d^p` over assigned pairs), `missed`,
/// `false_targets` (counts), `assigned`; `distance**p = localisation + c**p / 2 (missed +
/// false_targets)`.
#[pyfunction]
#[pyo3(signature = (x, y, c, p = 1.0))]
pub fn gospa<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    c: f64,
    p: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let (xs, ys, d) = point_sets(x, y)?;
    use quarry_eval::ospa::gospa as f;
    let g = by_dim!(d, f, &xs, &ys, p, c).map_err(map_err("gospa"))?;
    let out = PyDict::new(py);
    out.set_item("distance", g.distance)?;
    out.set_item("localisation", g.localisation)?;
    out.set_item("missed", g.missed)?;
    out.set_item("false_targets", g.false_targets)?;
    out.set_item("assigned", g.assigned)?;
    Ok(out)
}

/// Registers the metric functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(mot_metrics, m)?)?;
    m.add_function(wrap_pyfunction!(mot_metrics_files, m)?)?;
    m.add_function(wrap_pyfunction!(ospa, m)?)?;
    m.add_function(wrap_pyfunction!(gospa, m)?)?;
    Ok(())
}
