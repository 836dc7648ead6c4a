//! Filter bindings (quarry-filter): the stateful linear [`KalmanFilter`] class, functional
//! `ekf_predict` / `ekf_update` on `(x, P)` arrays with quarry's built-in motion and measurement
//! models, and the particle-filter weights and resamplers.
//!
//! The Kalman filter is quarry-filter's EKF ([`quarry_filter::ekf::predict`] /
//! [`quarry_filter::ekf::update`], Joseph form) on the linear models [`LinearMotion`] and
//! [`LinearMeasurement`], on fixed-size (stack, unrolled) matrices for state dimensions 1 to 6
//! and measurement dimensions 1 to 4; other sizes use [`LinearModel`] on dynamic matrices.
//! `filter_sequence` on the fixed-size path propagates only the mean once the covariance has
//! reached its floating-point fixed point (bit-identical output, see `FixedKf::run`).

use crate::args::{self, Values, data, map_err, value_error};
use crate::assoc::rows_to_py;
use nalgebra::{DMatrix, DVector, SMatrix, SVector};
use numpy::{PyArray1, PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use quarry_core::{Gaussian, MeasurementModel, MotionModel};
use quarry_filter::{
    ConstantVelocity2, ConstantVelocity3, CvNoise, FilterError, Position2, Position3, RangeBearing,
    RangeBearingCv, UpdateForm, ekf,
};

/// A linear motion model `x' = F x + w`, `w ~ N(0, Q)` (the time step is baked into `F`, `Q`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearMotion<const D: usize> {
    /// Transition matrix `F`.
    pub f: SMatrix<f64, D, D>,
    /// Process noise covariance `Q`.
    pub q: SMatrix<f64, D, D>,
}

impl<const D: usize> MotionModel<D> for LinearMotion<D> {
    type Control = ();
    #[inline]
    fn transition(&self, x: &SVector<f64, D>, _u: &(), _dt: f64) -> SVector<f64, D> {
        self.f * x
    }
    #[inline]
    fn jacobian(&self, _x: &SVector<f64, D>, _u: &(), _dt: f64) -> SMatrix<f64, D, D> {
        self.f
    }
    #[inline]
    fn process_noise(&self, _x: &SVector<f64, D>, _u: &(), _dt: f64) -> SMatrix<f64, D, D> {
        self.q
    }
}

/// A linear measurement model `z = H x + v`, `v ~ N(0, R)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearMeasurement<const D: usize, const Z: usize> {
    /// Measurement matrix `H`.
    pub h: SMatrix<f64, Z, D>,
    /// Measurement noise covariance `R`.
    pub r: SMatrix<f64, Z, Z>,
}

impl<const D: usize, const Z: usize> MeasurementModel<D, Z> for LinearMeasurement<D, Z> {
    #[inline]
    fn predict(&self, x: &SVector<f64, D>) -> SVector<f64, Z> {
        self.h * x
    }
    #[inline]
    fn jacobian(&self, _x: &SVector<f64, D>) -> SMatrix<f64, Z, D> {
        self.h
    }
    #[inline]
    fn noise(&self, _x: &SVector<f64, D>) -> SMatrix<f64, Z, Z> {
        self.r
    }
}

/// A linear-Gaussian model on dynamic matrices (the fallback for sizes without a fixed-size
/// build): `x' = F x + w, w ~ N(0, Q)`, `z = H x + v, v ~ N(0, R)`, filterpy's equations.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use quarry_py::filter::LinearModel;
/// let model = LinearModel {
///     f: DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 0.0, 1.0]),
///     q: DMatrix::identity(2, 2) * 0.01,
///     h: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
///     r: DMatrix::identity(1, 1) * 0.5,
/// };
/// let mut x = DVector::zeros(2);
/// let mut p = DMatrix::identity(2, 2);
/// model.predict(&mut x, &mut p);
/// model.update(&mut x, &mut p, &DVector::from_element(1, 1.0)).unwrap();
/// assert!(x[0] > 0.0 && x[0] < 1.0);
/// ```
#[derive(Debug, Clone)]
pub struct LinearModel {
    /// `F`, n × n.
    pub f: DMatrix<f64>,
    /// `Q`, n × n.
    pub q: DMatrix<f64>,
    /// `H`, m × n.
    pub h: DMatrix<f64>,
    /// `R`, m × m.
    pub r: DMatrix<f64>,
}

impl LinearModel {
    /// `x = F x`, `P = F P Fᵀ + Q`.
    pub fn predict(&self, x: &mut DVector<f64>, p: &mut DMatrix<f64>) {
        *x = &self.f * &*x;
        *p = &self.f * &*p * self.f.transpose() + &self.q;
    }

    /// Joseph-form update with `z`: `K = P Hᵀ S⁻¹`, `x += K y`,
    /// `P = (I − K H) P (I − K H)ᵀ + K R Kᵀ`.
    ///
    /// # Errors
    /// A message when `S` is singular or the result is not finite (state unchanged).
    pub fn update(
        &self,
        x: &mut DVector<f64>,
        p: &mut DMatrix<f64>,
        z: &DVector<f64>,
    ) -> Result<(), String> {
        let y = z - &self.h * &*x;
        let pht = &*p * self.h.transpose();
        let s = &self.h * &pht + &self.r;
        let si = s
            .try_inverse()
            .ok_or("innovation covariance S is singular")?;
        let k = pht * si;
        let nx = &*x + &k * y;
        let ikh = DMatrix::identity(x.len(), x.len()) - &k * &self.h;
        let np = &ikh * &*p * ikh.transpose() + &k * &self.r * k.transpose();
        if nx.iter().chain(np.iter()).any(|v| !v.is_finite()) {
            return Err("update produced a non-finite state".into());
        }
        *x = nx;
        *p = np;
        Ok(())
    }
}

/// What the [`KalmanFilter`] class needs of a filter, fixed-size or dynamic.
trait KfCore: Send + Sync {
    fn predict(&mut self) -> Result<(), String>;
    fn update(&mut self, z: &[f64]) -> Result<(), String>;
    /// predict + update per `m`-row of `zs`, appending each posterior mean to `out`.
    fn run(&mut self, zs: &[f64], m: usize, out: &mut Vec<f64>) -> Result<(), String> {
        for z in zs.chunks_exact(m) {
            self.predict()?;
            self.update(z)?;
            out.extend(self.x());
        }
        Ok(())
    }
    fn x(&self) -> Vec<f64>;
    /// `P`, row-major.
    fn p(&self) -> Vec<f64>;
}

/// The fixed-size Kalman filter: quarry-filter's [`ekf::predict`] / [`ekf::update`] (Joseph
/// form) on [`LinearMotion`] / [`LinearMeasurement`].
struct FixedKf<const D: usize, const Z: usize> {
    state: Gaussian<D>,
    motion: LinearMotion<D>,
    meas: LinearMeasurement<D, Z>,
}

/// `K ν` with the operation order of quarry-filter's update (`small::mul_vec`), so that the
/// steady-state path below gives the same bits as the full update.
#[inline]
fn gain_times<const D: usize, const Z: usize>(
    k: &SMatrix<f64, D, Z>,
    nu: &SVector<f64, Z>,
) -> SVector<f64, D> {
    let mut out = SVector::<f64, D>::zeros();
    for j in 0..Z {
        for i in 0..D {
            out[i] += k[(i, j)] * nu[j];
        }
    }
    out
}

impl<const D: usize, const Z: usize> FixedKf<D, Z> {
    /// One full predict + update; returns the predicted state as well.
    #[inline]
    fn full_step(&mut self, z: &SVector<f64, Z>) -> Result<Gaussian<D>, FilterError> {
        let pred = ekf::predict(&self.state, &self.motion, &(), 1.0)?;
        let (post, _) = ekf::update(&pred, &self.meas, z, UpdateForm::Joseph)?;
        self.state = post;
        Ok(pred)
    }
}

impl<const D: usize, const Z: usize> KfCore for FixedKf<D, Z> {
    #[inline]
    fn predict(&mut self) -> Result<(), String> {
        self.state =
            ekf::predict(&self.state, &self.motion, &(), 1.0).map_err(|e| e.to_string())?;
        Ok(())
    }
    #[inline]
    fn update(&mut self, z: &[f64]) -> Result<(), String> {
        let zv = SVector::<f64, Z>::from_column_slice(z);
        let (post, _) = ekf::update(&self.state, &self.meas, &zv, UpdateForm::Joseph)
            .map_err(|e| e.to_string())?;
        self.state = post;
        Ok(())
    }
    /// Full steps until the covariance reaches its floating-point fixed point (the posterior
    /// `P` of a step equals the previous one bit for bit — the Riccati recursion of a linear
    /// model does not depend on the data, so every later `P` and gain are then the same bits),
    /// then only the mean: `x⁻ = F x`, `x = x⁻ + K (z − H x⁻)`, with the operations of the full
    /// update in the same order, so the output is bit-identical to full steps.
    fn run(&mut self, zs: &[f64], _m: usize, out: &mut Vec<f64>) -> Result<(), String> {
        let err = |e: FilterError| e.to_string();
        let mut chunks = zs.chunks_exact(Z);
        let mut steady: Option<SMatrix<f64, D, Z>> = None;
        for z in chunks.by_ref() {
            let zv = SVector::<f64, Z>::from_column_slice(z);
            let before = self.state.cov;
            let pred = self.full_step(&zv).map_err(err)?;
            out.extend_from_slice(self.state.mean.as_slice());
            if self.state.cov == before {
                let mp = ekf::MeasurementPrediction::new(&pred, &self.meas).map_err(err)?;
                steady = Some(mp.gain);
                break;
            }
        }
        let Some(gain) = steady else {
            return Ok(());
        };
        let mut mean = self.state.mean;
        for z in chunks {
            let zv = SVector::<f64, Z>::from_column_slice(z);
            let xp = self.motion.transition(&mean, &(), 1.0);
            let nu = self.meas.residual(&zv, &self.meas.predict(&xp));
            let next = xp + gain_times(&gain, &nu);
            if !next.iter().all(|v| v.is_finite()) {
                self.state.mean = mean;
                return Err(FilterError::NonFiniteResult { what: "update" }.to_string());
            }
            mean = next;
            out.extend_from_slice(mean.as_slice());
        }
        self.state.mean = mean;
        Ok(())
    }
    fn x(&self) -> Vec<f64> {
        self.state.mean.as_slice().to_vec()
    }
    fn p(&self) -> Vec<f64> {
        self.state.cov.transpose().as_slice().to_vec()
    }
}

struct DynKf {
    model: LinearModel,
    x: DVector<f64>,
    p: DMatrix<f64>,
}

impl KfCore for DynKf {
    fn predict(&mut self) -> Result<(), String> {
        self.model.predict(&mut self.x, &mut self.p);
        if self.x.iter().chain(self.p.iter()).all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err("prediction produced a non-finite state".into())
        }
    }
    fn update(&mut self, z: &[f64]) -> Result<(), String> {
        let z = DVector::from_column_slice(z);
        self.model.update(&mut self.x, &mut self.p, &z)
    }
    fn x(&self) -> Vec<f64> {
        self.x.as_slice().to_vec()
    }
    fn p(&self) -> Vec<f64> {
        self.p.transpose().as_slice().to_vec()
    }
}

/// A row-major slice as a fixed-size matrix.
fn smat<const R: usize, const C: usize>(v: &[f64]) -> SMatrix<f64, R, C> {
    SMatrix::<f64, R, C>::from_row_slice(v)
}

/// A validated Gaussian (finite, symmetric positive definite `P`).
fn gaussian<const D: usize>(x: &[f64], p: &[f64]) -> PyResult<Gaussian<D>> {
    Gaussian::try_new(SVector::<f64, D>::from_column_slice(x), smat::<D, D>(p))
        .map_err(|e| value_error("P", e))
}

/// Builds the fixed-size filter for `(D, Z)`.
fn fixed<const D: usize, const Z: usize>(
    x: &[f64],
    p: &[f64],
    m: &[&[f64]; 4],
) -> PyResult<Box<dyn KfCore>> {
    let motion = LinearMotion {
        f: smat::<D, D>(m[0]),
        q: smat::<D, D>(m[1]),
    };
    let meas = LinearMeasurement {
        h: smat::<Z, D>(m[2]),
        r: smat::<Z, Z>(m[3]),
    };
    Ok(Box::new(FixedKf {
        state: gaussian::<D>(x, p)?,
        motion,
        meas,
    }))
}

/// `$body` with `const $D` set to the runtime dimension `$n` when it is one of the listed
/// sizes; `$fallback` otherwise.
macro_rules! with_dim {
    ($n:expr, $D:ident, $body:expr, $fallback:expr, [$($d:literal),*]) => {
        match $n {
            $($d => {
                const $D: usize = $d;
                $body
            })*
            _ => $fallback,
        }
    };
}

/// Reads a float64 matrix argument of the given shape.
fn mat_arg<'py>(
    ob: &Bound<'py, PyAny>,
    name: &str,
    rows: Option<usize>,
    cols: Option<usize>,
) -> PyResult<numpy::PyReadonlyArrayDyn<'py, f64>> {
    let expected = format!(
        "({}, {})",
        rows.map_or("n".into(), |r| r.to_string()),
        cols.map_or("n".into(), |c| c.to_string())
    );
    args::array::<f64>(ob, name, &expected, &[rows, cols], false, Values::Finite)
}

/// Reads a float64 vector argument of length `n`.
fn vec_arg<'py>(
    ob: &Bound<'py, PyAny>,
    name: &str,
    n: Option<usize>,
) -> PyResult<numpy::PyReadonlyArrayDyn<'py, f64>> {
    let expected = n.map_or("(n,)".into(), |n| format!("({n},)"));
    args::array::<f64>(ob, name, &expected, &[n], false, Values::Finite)
}

/// A linear Kalman filter holding `x`, `P` and the model `(F, Q, H, R)` (filterpy's
/// `KalmanFilter` equations, Joseph-form update).
///
/// State dimensions 1 to 6 with measurement dimensions 1 to 4 run on fixed-size matrices
/// through quarry-filter's EKF; other sizes on dynamic matrices.
#[pyclass(module = "quarry")]
pub struct KalmanFilter {
    core: Box<dyn KfCore>,
    dim_z: usize,
    dim_x: usize,
}

#[pymethods]
impl KalmanFilter {
    /// `KalmanFilter(x, P, F, Q, H, R)`; float64 arrays `(n,)`, `(n, n)`, `(n, n)`, `(n, n)`,
    /// `(m, n)`, `(m, m)`.
    #[new]
    #[pyo3(signature = (x, P, F, Q, H, R))]
    #[allow(non_snake_case)]
    fn py_new(
        x: &Bound<'_, PyAny>,
        P: &Bound<'_, PyAny>,
        F: &Bound<'_, PyAny>,
        Q: &Bound<'_, PyAny>,
        H: &Bound<'_, PyAny>,
        R: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let f = mat_arg(F, "F", None, None)?;
        let n = f.shape()[0];
        let f = mat_arg(F, "F", Some(n), Some(n))?;
        let q = mat_arg(Q, "Q", Some(n), Some(n))?;
        let h = mat_arg(H, "H", None, Some(n))?;
        let m = h.shape()[0];
        let r = mat_arg(R, "R", Some(m), Some(m))?;
        let x = vec_arg(x, "x", Some(n))?;
        let p = mat_arg(P, "P", Some(n), Some(n))?;
        let (xs, ps) = (data(&x), data(&p));
        let mats = [data(&f), data(&q), data(&h), data(&r)];
        let dynamic = || -> PyResult<Box<dyn KfCore>> {
            Ok(Box::new(DynKf {
                model: LinearModel {
                    f: DMatrix::from_row_slice(n, n, mats[0]),
                    q: DMatrix::from_row_slice(n, n, mats[1]),
                    h: DMatrix::from_row_slice(m, n, mats[2]),
                    r: DMatrix::from_row_slice(m, m, mats[3]),
                },
                x: DVector::from_column_slice(xs),
                p: DMatrix::from_row_slice(n, n, ps),
            }))
        };
        let core = with_dim!(
            n,
            D,
            with_dim!(
                m,
                Z,
                fixed::<D, Z>(xs, ps, &mats)?,
                dynamic()?,
                [1, 2, 3, 4]
            ),
            dynamic()?,
            [1, 2, 3, 4, 5, 6]
        );
        Ok(Self {
            core,
            dim_z: m,
            dim_x: n,
        })
    }

    /// Predicts one step: `x = F x`, `P = F P Fᵀ + Q`.
    fn predict(&mut self) -> PyResult<()> {
        self.core.predict().map_err(map_err("predict"))
    }

    /// Updates with the measurement `z` `(m,)`; the state is unchanged on error.
    fn update(&mut self, z: &Bound<'_, PyAny>) -> PyResult<()> {
        let z = vec_arg(z, "z", Some(self.dim_z))?;
        self.core.update(data(&z)).map_err(map_err("update"))
    }

    /// `predict()` then `update(z)`.
    fn step(&mut self, z: &Bound<'_, PyAny>) -> PyResult<()> {
        let z = vec_arg(z, "z", Some(self.dim_z))?;
        self.core.predict().map_err(map_err("step"))?;
        self.core.update(data(&z)).map_err(map_err("step"))
    }

    /// The state mean, shape `(n,)`.
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.core.x())
    }

    /// The state covariance, shape `(n, n)`.
    #[getter(P)]
    fn p<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        rows_to_py(py, self.core.p(), self.dim_x, self.dim_x)
    }

    /// Filters a whole `(T, m)` measurement array from the current state (predict + update per
    /// row, GIL released); returns the posterior means `(T, n)` and leaves the filter at the
    /// last state. On an error the filter stays at the last good step.
    fn filter_sequence<'py>(
        &mut self,
        py: Python<'py>,
        zs: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let expected = format!("(T, {})", self.dim_z);
        let zs = args::array::<f64>(
            zs,
            "zs",
            &expected,
            &[None, Some(self.dim_z)],
            false,
            Values::Finite,
        )?;
        let rows = zs.shape()[0];
        let (n, m) = (self.dim_x, self.dim_z);
        let zs = data(&zs);
        let core = &mut self.core;
        let out = py.detach(|| -> Result<Vec<f64>, String> {
            let mut out = Vec::with_capacity(rows * n);
            core.run(zs, m, &mut out)?;
            Ok(out)
        });
        rows_to_py(py, out.map_err(map_err("filter_sequence"))?, rows, n)
    }
}

/// `(x, P)` as numpy arrays.
type StateOut<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray2<f64>>);

fn state_to_py<'py, const D: usize>(py: Python<'py>, g: &Gaussian<D>) -> PyResult<StateOut<'py>> {
    Ok((
        PyArray1::from_slice(py, g.mean.as_slice()),
        rows_to_py(py, g.cov.transpose().as_slice().to_vec(), D, D)?,
    ))
}

/// Reads `(x, P)` with `x` `(n,)` and `P` `(n, n)`.
fn state_args<'py>(
    x: &Bound<'py, PyAny>,
    p: &Bound<'py, PyAny>,
) -> PyResult<(Vec<f64>, Vec<f64>, usize)> {
    let xa = vec_arg(x, "x", None)?;
    let n = xa.shape()[0];
    let pa = mat_arg(p, "P", Some(n), Some(n))?;
    Ok((data(&xa).to_vec(), data(&pa).to_vec(), n))
}

fn need_dim(model: &str, n: usize, dims: &[usize]) -> PyResult<()> {
    if dims.contains(&n) {
        Ok(())
    } else {
        Err(value_error(
            "x",
            format!("model {model:?} needs a state of dimension {dims:?}, got {n}"),
        ))
    }
}

fn cv_noise(q: Option<f64>, sigma_a: Option<f64>) -> PyResult<CvNoise> {
    match (q, sigma_a) {
        (Some(q), None) => Ok(CvNoise::Cwna { q }),
        (None, Some(s)) => Ok(CvNoise::Dwna { sigma_a: s }),
        _ => Err(value_error(
            "q",
            "give exactly one of q (continuous white-noise acceleration) or sigma_a (discrete)",
        )),
    }
}

fn do_predict<'py, const D: usize, M: MotionModel<D, Control = ()>>(
    py: Python<'py>,
    x: &[f64],
    p: &[f64],
    model: &M,
    dt: f64,
) -> PyResult<StateOut<'py>> {
    let g = gaussian::<D>(x, p)?;
    let out = ekf::predict(&g, model, &(), dt).map_err(map_err("ekf_predict"))?;
    state_to_py(py, &out)
}

/// EKF (and KF) time update of `(x, P)` with a built-in motion model; returns the new `(x, P)`.
///
/// `motion="cv2"`: planar constant velocity, state `[x, y, vx, vy]`; `motion="cv3"`: 3-D,
/// `[x, y, z, vx, vy, vz]`; both with either `q` (continuous white-noise acceleration, Stone
/// Soup's `ConstantVelocity(q)`) or `sigma_a` (discrete white-noise acceleration).
/// `motion="linear"`: `F` and `Q` (`dt` unused). `dt` in seconds, >= 0.
#[pyfunction]
#[pyo3(signature = (x, P, dt, motion = "cv2", q = None, sigma_a = None, F = None, Q = None))]
#[allow(non_snake_case, clippy::too_many_arguments)]
pub fn ekf_predict<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    P: &Bound<'py, PyAny>,
    dt: f64,
    motion: &str,
    q: Option<f64>,
    sigma_a: Option<f64>,
    F: Option<&Bound<'py, PyAny>>,
    Q: Option<&Bound<'py, PyAny>>,
) -> PyResult<StateOut<'py>> {
    let (xs, ps, n) = state_args(x, P)?;
    if !(dt.is_finite() && dt >= 0.0) {
        return Err(value_error("dt", format!("{dt} must be finite and >= 0")));
    }
    match motion {
        "cv2" => {
            need_dim(motion, n, &[4])?;
            let m =
                ConstantVelocity2::new(cv_noise(q, sigma_a)?).map_err(map_err("ekf_predict"))?;
            do_predict::<4, _>(py, &xs, &ps, &m, dt)
        }
        "cv3" => {
            need_dim(motion, n, &[6])?;
            let m =
                ConstantVelocity3::new(cv_noise(q, sigma_a)?).map_err(map_err("ekf_predict"))?;
            do_predict::<6, _>(py, &xs, &ps, &m, dt)
        }
        "linear" => {
            let (Some(f), Some(qq)) = (F, Q) else {
                return Err(value_error("F", "motion=\"linear\" needs F and Q"));
            };
            let f = mat_arg(f, "F", Some(n), Some(n))?;
            let qq = mat_arg(qq, "Q", Some(n), Some(n))?;
            with_dim!(
                n,
                D,
                {
                    let m = LinearMotion::<D> {
                        f: smat(data(&f)),
                        q: smat(data(&qq)),
                    };
                    do_predict::<D, _>(py, &xs, &ps, &m, 1.0)
                },
                Err(value_error(
                    "x",
                    format!("state dimension {n} is not supported by ekf_predict (1 to 6)")
                )),
                [1, 2, 3, 4, 5, 6]
            )
        }
        other => Err(value_error(
            "motion",
            format!("{other:?} is not \"cv2\", \"cv3\" or \"linear\""),
        )),
    }
}

/// `(x, P, nis, log_likelihood)` of an update.
type UpdateOut<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray2<f64>>,
    f64,
    f64,
);

fn do_update<'py, const D: usize, const Z: usize, H: MeasurementModel<D, Z>>(
    py: Python<'py>,
    x: &[f64],
    p: &[f64],
    z: &[f64],
    model: &H,
) -> PyResult<UpdateOut<'py>> {
    let g = gaussian::<D>(x, p)?;
    let zv = SVector::<f64, Z>::from_column_slice(z);
    let (post, inn) =
        ekf::update(&g, model, &zv, UpdateForm::Joseph).map_err(map_err("ekf_update"))?;
    let (xo, po) = state_to_py(py, &post)?;
    Ok((xo, po, inn.nis, inn.log_likelihood()))
}

fn r_arg<const Z: usize>(r: Option<&Bound<'_, PyAny>>) -> PyResult<SMatrix<f64, Z, Z>> {
    let r = r.ok_or_else(|| value_error("R", "is required"))?;
    let a = mat_arg(r, "R", Some(Z), Some(Z))?;
    Ok(smat(data(&a)))
}

/// EKF (and KF) measurement update of `(x, P)` with `z` and a built-in measurement model
/// (Joseph form); returns `(x, P, nis, log_likelihood)` — the normalised innovation squared and
/// `ln N(z; ẑ, S)` before the update.
///
/// `measurement="position2"`: `z = (x, y)`, the first two state components (state dimension 2,
/// 4 or 6), noise `R` `(2, 2)`; `"position3"`: `(x, y, z)` (state 3, 5 or 6); `"range_bearing"`:
/// `z = (range, bearing)` of the point `(x[0], x[1])` from a sensor at pose `sensor = (sx, sy,
/// stheta)` (state 2 or 4; the bearing residual is wrapped to (-pi, pi]), `R` `(2, 2)`;
/// `"linear"`: `H` `(m, n)` and `R` `(m, m)`.
#[pyfunction]
#[pyo3(signature = (x, P, z, measurement = "position2", R = None, H = None, sensor = (0.0, 0.0, 0.0)))]
#[allow(non_snake_case, clippy::too_many_arguments)]
pub fn ekf_update<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    P: &Bound<'py, PyAny>,
    z: &Bound<'py, PyAny>,
    measurement: &str,
    R: Option<&Bound<'py, PyAny>>,
    H: Option<&Bound<'py, PyAny>>,
    sensor: (f64, f64, f64),
) -> PyResult<UpdateOut<'py>> {
    let (xs, ps, n) = state_args(x, P)?;
    let za = vec_arg(z, "z", None)?;
    let zs = data(&za).to_vec();
    let need_z = |m: usize| -> PyResult<()> {
        if zs.len() == m {
            Ok(())
        } else {
            Err(value_error(
                "z",
                format!("expected shape ({m},), got ({},)", zs.len()),
            ))
        }
    };
    let e = map_err("ekf_update");
    match measurement {
        "position2" => {
            need_dim(measurement, n, &[2, 4, 6])?;
            need_z(2)?;
            let m = Position2::new(r_arg::<2>(R)?).map_err(&e)?;
            with_dim!(
                n,
                D,
                do_update::<D, 2, _>(py, &xs, &ps, &zs, &m),
                Err(value_error("x", "unsupported state dimension")),
                [2, 4, 6]
            )
        }
        "position3" => {
            need_dim(measurement, n, &[3, 5, 6])?;
            need_z(3)?;
            let m = Position3::new(r_arg::<3>(R)?).map_err(&e)?;
            with_dim!(
                n,
                D,
                do_update::<D, 3, _>(py, &xs, &ps, &zs, &m),
                Err(value_error("x", "unsupported state dimension")),
                [3, 5, 6]
            )
        }
        "range_bearing" => {
            need_dim(measurement, n, &[2, 4])?;
            need_z(2)?;
            let pose = args::pose("sensor", sensor)?;
            let point = RangeBearing::with_cov(pose, r_arg::<2>(R)?).map_err(&e)?;
            if n == 2 {
                do_update::<2, 2, _>(py, &xs, &ps, &zs, &point)
            } else {
                do_update::<4, 2, _>(py, &xs, &ps, &zs, &RangeBearingCv { point })
            }
        }
        "linear" => {
            let h = H.ok_or_else(|| value_error("H", "measurement=\"linear\" needs H and R"))?;
            let h = mat_arg(h, "H", None, Some(n))?;
            let m = h.shape()[0];
            need_z(m)?;
            let r = R.ok_or_else(|| value_error("R", "measurement=\"linear\" needs H and R"))?;
            let r = mat_arg(r, "R", Some(m), Some(m))?;
            let unsupported = || {
                Err(value_error(
                    "H",
                    format!("dimensions ({m}, {n}) are not supported by ekf_update (1-4, 1-6)"),
                ))
            };
            with_dim!(
                n,
                D,
                with_dim!(
                    m,
                    Z,
                    {
                        let model = LinearMeasurement::<D, Z> {
                            h: smat(data(&h)),
                            r: smat(data(&r)),
                        };
                        do_update::<D, Z, _>(py, &xs, &ps, &zs, &model)
                    },
                    unsupported(),
                    [1, 2, 3, 4]
                ),
                unsupported(),
                [1, 2, 3, 4, 5, 6]
            )
        }
        other => Err(value_error(
            "measurement",
            format!(
                "{other:?} is not \"position2\", \"position3\", \"range_bearing\" or \"linear\""
            ),
        )),
    }
}

/// Normalises log-weights: returns `(weights, log_sum)` with `weights` summing to 1.
#[pyfunction]
pub fn normalise_log_weights<'py>(
    py: Python<'py>,
    log_w: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyArray1<f64>>, f64)> {
    let a = args::array::<f64>(
        log_w,
        "log_w",
        "(N,)",
        &[None],
        false,
        Values::FiniteOrNegInf,
    )?;
    let (w, ls) = quarry_filter::particles::normalise_log(data(&a))
        .map_err(map_err("normalise_log_weights"))?;
    Ok((PyArray1::from_vec(py, w), ls))
}

/// Effective sample size `1 / Σ w²` of normalised weights.
#[pyfunction]
pub fn effective_sample_size(weights: &Bound<'_, PyAny>) -> PyResult<f64> {
    let a = args::array::<f64>(weights, "weights", "(N,)", &[None], false, Values::Finite)?;
    Ok(quarry_filter::particles::effective_sample_size(data(&a)))
}

/// Ancestor indices `(N,)` int64 drawn from `weights` `(N,)` (non-negative, need not sum to 1)
/// by `scheme` ("systematic", "stratified", "multinomial", "residual") with a generator seeded by
/// `seed` (Xoshiro256++): the same seed gives the same indices.
#[pyfunction]
#[pyo3(signature = (weights, seed, scheme = "systematic"))]
pub fn resample<'py>(
    py: Python<'py>,
    weights: &Bound<'py, PyAny>,
    seed: u64,
    scheme: &str,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    use rand::SeedableRng;
    let a = args::array::<f64>(weights, "weights", "(N,)", &[None], false, Values::Finite)?;
    let s = scheme_arg(scheme)?;
    let w = data(&a);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut out = Vec::with_capacity(w.len());
    py.detach(|| s.resample_into(w, &mut rng, &mut out))
        .map_err(|e: FilterError| value_error("weights", e))?;
    Ok(PyArray1::from_vec(
        py,
        out.into_iter()
            .map(|i| i64::try_from(i).unwrap_or(-1))
            .collect(),
    ))
}

/// Parses a resampling scheme name.
fn scheme_arg(scheme: &str) -> PyResult<quarry_filter::particles::ResamplingScheme> {
    use quarry_filter::particles::ResamplingScheme;
    match scheme {
        "systematic" => Ok(ResamplingScheme::Systematic),
        "stratified" => Ok(ResamplingScheme::Stratified),
        "multinomial" => Ok(ResamplingScheme::Multinomial),
        "residual" => Ok(ResamplingScheme::Residual),
        other => Err(value_error(
            "scheme",
            format!(
                "{other:?} is not \"systematic\", \"stratified\", \"multinomial\" or \"residual\""
            ),
        )),
    }
}

/// A bootstrap particle filter on the planar constant-velocity model with position
/// measurements, as `peers/bench_pf.py` runs it: each step propagates every particle with
/// `ConstantVelocity2` (continuous white-noise acceleration `q`) plus a draw of its process noise,
/// weights by `ln N(z; (x, y), R)` (log domain, normalised), records the weighted mean, and
/// resamples with `scheme` when the effective sample size falls below `ess_threshold · N`
/// (1.0 = every step).
///
/// `particles` `(N, 4)` initial states `[x, y, vx, vy]`, `zs` `(T, 2)`; returns the weighted
/// means `(T, 4)`. Reproducible: the generator (Xoshiro256++) is seeded with `seed`.
#[pyfunction]
#[pyo3(signature = (particles, zs, dt, q, R, seed, scheme = "systematic", ess_threshold = 1.0))]
#[allow(non_snake_case, clippy::too_many_arguments)]
pub fn particle_filter_cv2<'py>(
    py: Python<'py>,
    particles: &Bound<'py, PyAny>,
    zs: &Bound<'py, PyAny>,
    dt: f64,
    q: f64,
    R: &Bound<'py, PyAny>,
    seed: u64,
    scheme: &str,
    ess_threshold: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    use quarry_filter::particles::{effective_sample_size, normalise_log_into};
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let pa = args::array::<f64>(
        particles,
        "particles",
        "(N, 4)",
        &[None, Some(4)],
        false,
        Values::Finite,
    )?;
    let za = args::array::<f64>(zs, "zs", "(T, 2)", &[None, Some(2)], false, Values::Finite)?;
    let r = r_arg::<2>(Some(R))?;
    let s = scheme_arg(scheme)?;
    if !(dt.is_finite() && dt >= 0.0) {
        return Err(value_error("dt", format!("{dt} must be finite and >= 0")));
    }
    if !(0.0..=1.0).contains(&ess_threshold) {
        return Err(value_error(
            "ess_threshold",
            format!("{ess_threshold} is not in [0, 1]"),
        ));
    }
    let cv = ConstantVelocity2::cwna(q).map_err(|e| value_error("q", e))?;
    let meas = Position2::new(r).map_err(|e| value_error("R", e))?;
    let rchol = r
        .cholesky()
        .ok_or_else(|| value_error("R", "not positive definite"))?;
    let (rinv, rlogdet) = (
        rchol.inverse(),
        2.0 * rchol.l().diagonal().map(f64::ln).sum(),
    );
    let qm = cv.process_noise(&SVector::zeros(), &(), dt);
    // CWNA's Q is positive definite for dt > 0; dt = 0 means no noise at all
    let lq = qm
        .cholesky()
        .map_or_else(SMatrix::<f64, 4, 4>::zeros, |c| c.l());
    let mut x: Vec<SVector<f64, 4>> = data(&pa)
        .chunks_exact(4)
        .map(SVector::<f64, 4>::from_column_slice)
        .collect();
    let zs = data(&za);
    let n = x.len();
    let steps = zs.len() / 2;
    let out = py.detach(|| -> Result<Vec<f64>, String> {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut out = Vec::with_capacity(steps * 4);
        let mut logw = vec![0.0; n];
        let mut w = vec![0.0; n];
        let mut anc = Vec::with_capacity(n);
        let mut next = x.clone();
        for z in zs.chunks_exact(2) {
            let z = nalgebra::Vector2::new(z[0], z[1]);
            for (xi, lw) in x.iter_mut().zip(logw.iter_mut()) {
                let e = SVector::<f64, 4>::from_fn(|_, _| StandardNormal.sample(&mut rng));
                *xi = cv.transition(xi, &(), dt) + lq * e;
                let nu = z - meas.predict(xi);
                *lw += -0.5 * (nu.dot(&(rinv * nu)) + rlogdet);
            }
            normalise_log_into(&logw, &mut w).map_err(|e| e.to_string())?;
            let mean = x
                .iter()
                .zip(&w)
                .fold(SVector::<f64, 4>::zeros(), |acc, (xi, wi)| acc + xi * *wi);
            out.extend_from_slice(mean.as_slice());
            #[allow(clippy::cast_precision_loss)]
            let resample =
                effective_sample_size(&w) < ess_threshold * n as f64 || ess_threshold >= 1.0;
            if resample {
                s.resample_into(&w, &mut rng, &mut anc)
                    .map_err(|e| e.to_string())?;
                for (dst, &a) in next.iter_mut().zip(&anc) {
                    *dst = x[a];
                }
                std::mem::swap(&mut x, &mut next);
                logw.fill(0.0);
            } else {
                for (lw, wi) in logw.iter_mut().zip(&w) {
                    *lw = wi.ln();
                }
            }
        }
        Ok(out)
    });
    rows_to_py(py, out.map_err(map_err("particle_filter_cv2"))?, steps, 4)
}

/// Registers the filter functions and classes.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<KalmanFilter>()?;
    m.add_function(wrap_pyfunction!(ekf_predict, m)?)?;
    m.add_function(wrap_pyfunction!(ekf_update, m)?)?;
    m.add_function(wrap_pyfunction!(normalise_log_weights, m)?)?;
    m.add_function(wrap_pyfunction!(effective_sample_size, m)?)?;
    m.add_function(wrap_pyfunction!(resample, m)?)?;
    m.add_function(wrap_pyfunction!(particle_filter_cv2, m)?)?;
    Ok(())
}
