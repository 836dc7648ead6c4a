//! Point-cloud bindings (quarry-cloud): MeanShift, 2-D ICP and the closed-form rigid fit, the
//! paper's chi-square background model and the per-beam variance chi-square test.

use crate::args::{self, Values, data, map_err, value_error};
use crate::assoc::rows_to_py;
use numpy::{PyArray1, PyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use quarry_cloud::background::{ChiSquareConfig, VarianceChi2Test as QVariance};
use quarry_cloud::cluster::{Kernel, MeanShift, Seeding};
use quarry_cloud::icp::{Icp2d, rigid_2d};
use quarry_core::{BackgroundModel, BeamLabel, Point2, PolarScan, ScanGeometry, SensorId, TimeUs};

/// Reads `(N, 2)` float64 points (`N` may be 0 when `allow_empty`).
fn points(ob: &Bound<'_, PyAny>, name: &str, allow_empty: bool) -> PyResult<Vec<Point2>> {
    let a = args::array::<f64>(
        ob,
        name,
        "(N, 2)",
        &[None, Some(2)],
        allow_empty,
        Values::Finite,
    )?;
    Ok(data(&a)
        .chunks_exact(2)
        .map(|c| Point2::new(c[0], c[1]))
        .collect())
}

/// Result of `mean_shift`: (labels, modes, sizes).
type ClusterOut<'py> = (
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<i64>>,
);

/// MeanShift clustering of 2-D points (spec 003 §3; deterministic).
///
/// `points` `(N, 2)`; `bandwidth` h (metres); `kernel` `"flat"` (mean of the points within h) or
/// `"gaussian"`; `seeding` `"bins"` (one seed per occupied h/2 cell) or `"all"` (every point);
/// modes closer than `merge_radius` (default h/2) merge; clusters smaller than
/// `min_cluster_size` and points farther than `noise_factor · h` from every mode are noise.
/// Returns `(labels (N,) int64, -1 = noise; modes (K, 2); sizes (K,))`.
#[pyfunction]
#[pyo3(signature = (points, bandwidth = 0.3, kernel = "flat", seeding = "bins", min_cluster_size = 3, tolerance = 1e-3, max_iter = 50, merge_radius = None, noise_factor = 2.0))]
#[allow(clippy::too_many_arguments)]
pub fn mean_shift<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    bandwidth: f64,
    kernel: &str,
    seeding: &str,
    min_cluster_size: usize,
    tolerance: f64,
    max_iter: u32,
    merge_radius: Option<f64>,
    noise_factor: f64,
) -> PyResult<ClusterOut<'py>> {
    let pts = self::points(points, "points", true)?;
    let ms = MeanShift {
        bandwidth,
        kernel: match kernel {
            "flat" => Kernel::Flat,
            "gaussian" => Kernel::Gaussian,
            other => {
                return Err(value_error(
                    "kernel",
                    format!("{other:?} is not \"flat\" or \"gaussian\""),
                ));
            }
        },
        seeding: match seeding {
            "bins" => Seeding::Bins,
            "all" => Seeding::AllPoints,
            other => {
                return Err(value_error(
                    "seeding",
                    format!("{other:?} is not \"bins\" or \"all\""),
                ));
            }
        },
        tolerance,
        max_iter,
        merge_radius,
        min_cluster_size,
        noise_factor,
    };
    let c = py.detach(|| ms.run(&pts)).map_err(map_err("mean_shift"))?;
    let labels = c.labels.iter().map(|l| l.map_or(-1, i64::from)).collect();
    let modes: Vec<f64> = c.modes.iter().flat_map(|m| [m.x, m.y]).collect();
    let sizes = c
        .sizes
        .iter()
        .map(|&s| i64::try_from(s).unwrap_or(i64::MAX))
        .collect();
    Ok((
        PyArray1::from_vec(py, labels),
        rows_to_py(py, modes, c.modes.len(), 2)?,
        PyArray1::from_vec(py, sizes),
    ))
}

/// Closed-form least-squares rigid transform `(x, y, theta)` mapping `src` `(N, 2)` onto `dst`
/// `(N, 2)` (paired rows), optionally weighted by `weights` `(N,)`.
#[pyfunction]
#[pyo3(signature = (src, dst, weights = None))]
pub fn rigid_transform_2d(
    src: &Bound<'_, PyAny>,
    dst: &Bound<'_, PyAny>,
    weights: Option<&Bound<'_, PyAny>>,
) -> PyResult<(f64, f64, f64)> {
    let p = points(src, "src", false)?;
    let q = points(dst, "dst", false)?;
    if q.len() != p.len() {
        return Err(value_error(
            "dst",
            format!("expected shape ({}, 2), got ({}, 2)", p.len(), q.len()),
        ));
    }
    let w = weights
        .filter(|w| !w.is_none())
        .map(|w| {
            let shape = format!("({},)", p.len());
            args::array::<f64>(
                w,
                "weights",
                &shape,
                &[Some(p.len())],
                false,
                Values::Finite,
            )
            .map(|a| data(&a).to_vec())
        })
        .transpose()?;
    let t = rigid_2d(&p, &q, w.as_deref(), 0.0).map_err(map_err("rigid_transform_2d"))?;
    Ok((t.x, t.y, t.theta))
}

/// 2-D ICP (spec 003 §2.6): the pose `(x, y, theta)` mapping `model` `(M, 2)` (its own frame)
/// onto `data` `(N, 2)`, from `init`.
///
/// `preset`: `"default"` (trimmed point-to-point, data→model), `"contour"` (the model is an
/// ordered closed contour, the tracker's setting), `"contour_point_to_line"`, `"literal"`
/// (the paper's model→data step). `max_iter`, `rms_stop`, `delta_stop` override the preset.
/// Returns a dict: `pose` (x, y, theta), `rms`, `inliers`, `iters`, `converged`.
#[pyfunction]
#[pyo3(signature = (model, data, init = (0.0, 0.0, 0.0), preset = "default", max_iter = None, rms_stop = None, delta_stop = None))]
#[allow(clippy::too_many_arguments)]
pub fn icp_2d<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyAny>,
    data: &Bound<'py, PyAny>,
    init: (f64, f64, f64),
    preset: &str,
    max_iter: Option<u32>,
    rms_stop: Option<f64>,
    delta_stop: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let m = points(model, "model", false)?;
    let d = points(data, "data", false)?;
    let mut icp = match preset {
        "default" => Icp2d::default(),
        "contour" => Icp2d::contour(),
        "contour_point_to_line" => Icp2d::contour_point_to_line(),
        "literal" => Icp2d::literal(),
        other => {
            return Err(value_error(
                "preset",
                format!(
                    "{other:?} is not \"default\", \"contour\", \"contour_point_to_line\" or \"literal\""
                ),
            ));
        }
    };
    if let Some(v) = max_iter {
        icp.max_iter = v;
    }
    if let Some(v) = rms_stop {
        icp.rms_stop = v;
    }
    if let Some(v) = delta_stop {
        icp.delta_stop = v;
    }
    let init = args::pose("init", init)?;
    let r = py
        .detach(|| icp.register_detailed(&m, &d, init))
        .map_err(map_err("icp_2d"))?;
    let out = PyDict::new(py);
    out.set_item("pose", (r.pose.x, r.pose.y, r.pose.theta))?;
    out.set_item("rms", r.rms)?;
    out.set_item("inliers", r.inliers)?;
    out.set_item("iters", r.iters)?;
    out.set_item("converged", r.converged)?;
    Ok(out)
}

/// Largest accepted |time stamp|, seconds (about 31 700 years: Unix times fit, and differences of
/// two stamps in microseconds stay far inside `i64`).
pub const MAX_STAMP_S: f64 = 1e12;

/// A scan of ranges in metres (0, out of range or beyond 65.535 m = no return) at `t` seconds,
/// as quarry's millimetre [`PolarScan`].
///
/// # Errors
/// `ValueError` naming `ranges` when the geometry is unusable or the beam count is wrong, or `t`
/// when it is not finite or beyond [`MAX_STAMP_S`].
pub fn polar_scan(ranges: &[f64], t: f64, seq: u32, geometry: ScanGeometry) -> PyResult<PolarScan> {
    if !(t.is_finite() && t.abs() <= MAX_STAMP_S) {
        return Err(value_error(
            "t",
            format!("time stamp {t} s is not finite or beyond ±1e12 s"),
        ));
    }
    let mm = ranges
        .iter()
        .map(|&r| {
            let v = (r * 1000.0).round();
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            if v > 0.0 && v <= f64::from(u16::MAX) {
                v as u16
            } else {
                0
            }
        })
        .collect();
    #[allow(clippy::cast_possible_truncation)]
    let stamp = TimeUs((t * 1e6).round() as i64);
    PolarScan::try_new(SensorId(0), seq, stamp, mm, geometry).map_err(|e| value_error("ranges", e))
}

/// Most beams per scan accepted by [`ChiSquareBackground`] (real 2-D scanners have a few
/// thousand).
pub const MAX_BEAMS: u32 = 100_000;
/// Longest window (scans) accepted by [`ChiSquareBackground`] (the lidar tracker's own limit).
pub const MAX_WINDOW: usize = 4000;

/// Label codes returned by the background models.
fn label_code(l: BeamLabel) -> i8 {
    match l {
        BeamLabel::Static => 0,
        BeamLabel::Dynamic => 1,
        BeamLabel::Invalid => 2,
    }
}

/// The chi-square background model of spec 003 §2.2 for one laser scanner: per-beam window of
/// the last `window` readings, static probability `exp(-D²/2) > p_threshold` with tolerance
/// `kappa`, the region constraint (radius `region_radius`), and (with `long_term=True`) the
/// long-term background learned over the first 200 scans.
///
/// `classify(ranges, t)` labels one scan: `ranges` `(n_beams,)` float64 metres (0 or anything
/// outside `[range_min, range_max]` = no return), `t` seconds (non-decreasing); returns int8
/// labels, 0 = static, 1 = dynamic, 2 = invalid / still learning.
#[pyclass(module = "quarry")]
pub struct ChiSquareBackground {
    inner: quarry_cloud::background::ChiSquareBackground,
    geometry: ScanGeometry,
    seq: u32,
}

#[pymethods]
impl ChiSquareBackground {
    /// `ChiSquareBackground(n_beams, angle_min, angle_increment, range_min=0.1, range_max=30.0,
    /// scan_period=0.025, window=40, p_threshold=0.9, kappa=7.0, region_constraint=True,
    /// region_radius=0.3, long_term=True)`; angles in radians.
    #[new]
    #[pyo3(signature = (n_beams, angle_min, angle_increment, range_min = 0.1, range_max = 30.0, scan_period = 0.025, window = 40, p_threshold = 0.9, kappa = 7.0, region_constraint = true, region_radius = 0.3, long_term = true))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        n_beams: u32,
        angle_min: f64,
        angle_increment: f64,
        range_min: f64,
        range_max: f64,
        scan_period: f64,
        window: usize,
        p_threshold: f64,
        kappa: f64,
        region_constraint: bool,
        region_radius: f64,
        long_term: bool,
    ) -> PyResult<Self> {
        // the model allocates n_beams × window cells up front: bound both (a 2³¹-beam scanner
        // would exhaust memory and abort the interpreter instead of raising)
        if !(1..=MAX_BEAMS).contains(&n_beams) {
            return Err(value_error(
                "n_beams",
                format!("{n_beams} is not in 1..={MAX_BEAMS}"),
            ));
        }
        if !(1..=MAX_WINDOW).contains(&window) {
            return Err(value_error(
                "window",
                format!("{window} is not in 1..={MAX_WINDOW}"),
            ));
        }
        let geometry = ScanGeometry {
            n_beams,
            angle_min,
            angle_increment,
            range_min,
            range_max,
            scan_period,
        };
        let base = if long_term {
            ChiSquareConfig::default()
        } else {
            ChiSquareConfig::literal()
        };
        let cfg = ChiSquareConfig {
            window,
            p_threshold,
            kappa,
            region_constraint,
            region_radius,
            ..base
        };
        let inner = quarry_cloud::background::ChiSquareBackground::new(&geometry, cfg)
            .map_err(map_err("ChiSquareBackground"))?;
        Ok(Self {
            inner,
            geometry,
            seq: 0,
        })
    }

    /// Labels one scan and updates the model.
    #[pyo3(signature = (ranges, t))]
    fn classify<'py>(
        &mut self,
        py: Python<'py>,
        ranges: &Bound<'py, PyAny>,
        t: f64,
    ) -> PyResult<Bound<'py, PyArray1<i8>>> {
        let n = self.geometry.n_beams as usize;
        let a = args::array::<f64>(
            ranges,
            "ranges",
            &format!("({n},)"),
            &[Some(n)],
            false,
            Values::Finite,
        )?;
        let t = args::finite("t", t)?;
        let scan = polar_scan(data(&a), t, self.seq, self.geometry)?;
        self.seq = self.seq.wrapping_add(1);
        let inner = &mut self.inner;
        let labels = py
            .detach(|| inner.classify(&scan))
            .map_err(map_err("ChiSquareBackground.classify"))?;
        Ok(PyArray1::from_vec(
            py,
            labels.into_iter().map(label_code).collect(),
        ))
    }

    /// Number of scans classified so far.
    #[getter]
    fn scans_seen(&self) -> u64 {
        self.inner.scans_seen()
    }
}

/// The per-beam variance chi-square test of `peers/bench_chi2.py`: with the window mean `mu`
/// and variance `s2 = max(var_ddof1, min_sigma²)` of each beam, a range `r` is foreground iff
/// `(r - mu)² / s2 > threshold` and `r < mu`.
///
/// `VarianceChi2Test(window, min_sigma=0.005, threshold=10.83)` with `window` `(m, beams)`
/// float64 metres (m >= 2).
#[pyclass(module = "quarry")]
pub struct VarianceChi2Test {
    inner: QVariance,
    beams: usize,
}

#[pymethods]
impl VarianceChi2Test {
    #[new]
    #[pyo3(signature = (window, min_sigma = 0.005, threshold = 10.83))]
    fn py_new(window: &Bound<'_, PyAny>, min_sigma: f64, threshold: f64) -> PyResult<Self> {
        let a = args::array::<f64>(
            window,
            "window",
            "(m, beams)",
            &[None, None],
            false,
            Values::Finite,
        )?;
        let beams = a.shape()[1];
        let rows: Vec<Vec<f64>> = data(&a).chunks_exact(beams).map(<[f64]>::to_vec).collect();
        let min_sigma = args::finite("min_sigma", min_sigma)?;
        let threshold = args::finite("threshold", threshold)?;
        let inner =
            QVariance::new(&rows, min_sigma, threshold).map_err(|e| value_error("window", e))?;
        Ok(Self { inner, beams })
    }

    /// Foreground flags `(beams,)` bool of `ranges` against the window (no update).
    fn test<'py>(
        &self,
        py: Python<'py>,
        ranges: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let n = self.beams;
        let a = self.ranges(ranges)?;
        let mut out = Vec::with_capacity(n);
        self.inner
            .test(data(&a), &mut out)
            .map_err(|e| value_error("ranges", e))?;
        Ok(PyArray1::from_vec(py, out))
    }

    /// Pushes `ranges` `(beams,)` into the window, replacing the oldest scan.
    fn push(&mut self, ranges: &Bound<'_, PyAny>) -> PyResult<()> {
        let a = self.ranges(ranges)?;
        self.inner
            .push(data(&a))
            .map_err(|e| value_error("ranges", e))
    }
}

impl VarianceChi2Test {
    /// Reads one scan `(beams,)` of ranges.
    fn ranges<'py>(&self, ob: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
        let n = self.beams;
        args::array::<f64>(
            ob,
            "ranges",
            &format!("({n},)"),
            &[Some(n)],
            false,
            Values::Finite,
        )
    }
}

/// Registers the point-cloud functions and classes.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(mean_shift, m)?)?;
    m.add_function(wrap_pyfunction!(rigid_transform_2d, m)?)?;
    m.add_function(wrap_pyfunction!(icp_2d, m)?)?;
    m.add_class::<ChiSquareBackground>()?;
    m.add_class::<VarianceChi2Test>()?;
    Ok(())
}
