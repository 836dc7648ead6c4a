//! Python bindings for quarry, importable as `import quarry` (built with maturin or by
//! `cargo build -p quarry-py`, which produces `libquarry_py.so`).
//!
//! This first cut binds a linear Kalman filter: [`KalmanFilter`] (a stateful class holding
//! `x`, `P` and the model so that a per-step call does not re-validate the model arrays) and
//! `filter_sequence` over a `(T, m)` measurement array. The numerical core is pure Rust and can
//! be used from Rust directly:
//!
//! ```
//! use nalgebra::{DMatrix, DVector};
//! use quarry_py::LinearModel;
//! let model = LinearModel::new(
//!     DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 0.0, 1.0]),
//!     DMatrix::identity(2, 2) * 0.01,
//!     DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
//!     DMatrix::identity(1, 1) * 0.5,
//! )
//! .unwrap();
//! let mut x = DVector::zeros(2);
//! let mut p = DMatrix::identity(2, 2);
//! model.step(&mut x, &mut p, &DVector::from_element(1, 1.0)).unwrap();
//! assert!(x[0] > 0.0 && x[0] < 1.0);
//! ```

pub mod args;
pub mod assoc;
pub mod metrics;
pub mod vision;

use nalgebra::{DMatrix, DVector};
use numpy::{
    PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// Errors of the bindings; each becomes a Python `ValueError` with this message.
#[derive(Debug, thiserror::Error)]
pub enum BindError {
    /// An argument has the wrong shape.
    #[error("{arg}: expected shape {expected}, got {got:?}")]
    Shape {
        /// Argument name.
        arg: &'static str,
        /// Expected shape, in words.
        expected: String,
        /// Actual shape.
        got: Vec<usize>,
    },
    /// An argument contains NaN or infinity.
    #[error("{0}: contains NaN or infinity")]
    NonFinite(&'static str),
    /// The innovation covariance is not invertible.
    #[error("innovation covariance S is singular")]
    Singular,
}

impl From<BindError> for PyErr {
    fn from(e: BindError) -> Self {
        PyValueError::new_err(e.to_string())
    }
}

/// A linear-Gaussian model: `x' = F x + w, w ~ N(0, Q)`, `z = H x + v, v ~ N(0, R)`.
#[derive(Debug, Clone)]
pub struct LinearModel {
    f: DMatrix<f64>,
    q: DMatrix<f64>,
    h: DMatrix<f64>,
    r: DMatrix<f64>,
}

fn check(arg: &'static str, m: &DMatrix<f64>, rows: usize, cols: usize) -> Result<(), BindError> {
    if m.nrows() != rows || m.ncols() != cols || rows == 0 || cols == 0 {
        return Err(BindError::Shape {
            arg,
            expected: format!("({rows}, {cols}), non-empty"),
            got: vec![m.nrows(), m.ncols()],
        });
    }
    if m.iter().any(|v| !v.is_finite()) {
        return Err(BindError::NonFinite(arg));
    }
    Ok(())
}

impl LinearModel {
    /// Validates and builds the model (`F` n x n, `Q` n x n, `H` m x n, `R` m x m).
    ///
    /// # Errors
    /// [`BindError::Shape`] or [`BindError::NonFinite`] naming the offending matrix.
    pub fn new(
        f: DMatrix<f64>,
        q: DMatrix<f64>,
        h: DMatrix<f64>,
        r: DMatrix<f64>,
    ) -> Result<Self, BindError> {
        let n = f.nrows();
        let m = h.nrows();
        check("F", &f, n, n)?;
        check("Q", &q, n, n)?;
        check("H", &h, m, n)?;
        check("R", &r, m, m)?;
        Ok(Self { f, q, h, r })
    }

    /// State dimension.
    pub fn dim_x(&self) -> usize {
        self.f.nrows()
    }

    /// Measurement dimension.
    pub fn dim_z(&self) -> usize {
        self.h.nrows()
    }

    /// Prediction: `x = F x`, `P = F P F' + Q` (filterpy's form).
    pub fn predict(&self, x: &mut DVector<f64>, p: &mut DMatrix<f64>) {
        *x = &self.f * &*x;
        *p = &self.f * &*p * self.f.transpose() + &self.q;
    }

    /// Update with `z`, filterpy's form: `K = P H' S^-1`, `x += K y`,
    /// `P = (I - K H) P (I - K H)' + K R K'`.
    ///
    /// # Errors
    /// [`BindError::Singular`] when `S` cannot be inverted.
    pub fn update(
        &self,
        x: &mut DVector<f64>,
        p: &mut DMatrix<f64>,
        z: &DVector<f64>,
    ) -> Result<(), BindError> {
        let y = z - &self.h * &*x;
        let pht = &*p * self.h.transpose();
        let s = &self.h * &pht + &self.r;
        let si = s.try_inverse().ok_or(BindError::Singular)?;
        let k = pht * si;
        *x += &k * y;
        let ikh = DMatrix::identity(self.dim_x(), self.dim_x()) - &k * &self.h;
        *p = &ikh * &*p * ikh.transpose() + &k * &self.r * k.transpose();
        Ok(())
    }

    /// One predict + update step.
    ///
    /// # Errors
    /// As [`LinearModel::update`].
    pub fn step(
        &self,
        x: &mut DVector<f64>,
        p: &mut DMatrix<f64>,
        z: &DVector<f64>,
    ) -> Result<(), BindError> {
        self.predict(x, p);
        self.update(x, p, z)
    }
}

fn mat(arg: &'static str, a: &PyReadonlyArray2<'_, f64>) -> Result<DMatrix<f64>, BindError> {
    let shape = a.shape().to_vec();
    let view = a.as_array();
    let m = DMatrix::from_fn(shape[0], shape[1], |i, j| view[[i, j]]);
    if shape[0] == 0 || shape[1] == 0 {
        return Err(BindError::Shape {
            arg,
            expected: "non-empty".into(),
            got: shape,
        });
    }
    if m.iter().any(|v| !v.is_finite()) {
        return Err(BindError::NonFinite(arg));
    }
    Ok(m)
}

fn vec1(
    arg: &'static str,
    a: &PyReadonlyArray1<'_, f64>,
    n: usize,
) -> Result<DVector<f64>, BindError> {
    let view = a.as_array();
    if view.len() != n {
        return Err(BindError::Shape {
            arg,
            expected: format!("({n},)"),
            got: vec![view.len()],
        });
    }
    let v = DVector::from_iterator(n, view.iter().copied());
    if v.iter().any(|x| !x.is_finite()) {
        return Err(BindError::NonFinite(arg));
    }
    Ok(v)
}

fn extract2<'py>(
    arg: &'static str,
    ob: &Bound<'py, PyAny>,
) -> PyResult<PyReadonlyArray2<'py, f64>> {
    ob.extract()
        .map_err(|_| PyTypeError::new_err(format!("{arg}: expected a 2-D float64 numpy array")))
}

fn extract1<'py>(
    arg: &'static str,
    ob: &Bound<'py, PyAny>,
) -> PyResult<PyReadonlyArray1<'py, f64>> {
    ob.extract()
        .map_err(|_| PyTypeError::new_err(format!("{arg}: expected a 1-D float64 numpy array")))
}

/// A linear Kalman filter holding `x`, `P` and the model `(F, Q, H, R)`.
#[pyclass(module = "quarry")]
pub struct KalmanFilter {
    model: LinearModel,
    x: DVector<f64>,
    p: DMatrix<f64>,
}

#[pymethods]
impl KalmanFilter {
    /// `KalmanFilter(x, P, F, Q, H, R)`; all float64 arrays.
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
        let model = LinearModel::new(
            mat("F", &extract2("F", F)?)?,
            mat("Q", &extract2("Q", Q)?)?,
            mat("H", &extract2("H", H)?)?,
            mat("R", &extract2("R", R)?)?,
        )?;
        let n = model.dim_x();
        let x = vec1("x", &extract1("x", x)?, n)?;
        let p = mat("P", &extract2("P", P)?)?;
        check("P", &p, n, n)?;
        Ok(Self { model, x, p })
    }

    /// Predicts one step.
    fn predict(&mut self) {
        self.model.predict(&mut self.x, &mut self.p);
    }

    /// Updates with the measurement `z` (shape `(m,)`).
    fn update(&mut self, z: &Bound<'_, PyAny>) -> PyResult<()> {
        let z = vec1("z", &extract1("z", z)?, self.model.dim_z())?;
        Ok(self.model.update(&mut self.x, &mut self.p, &z)?)
    }

    /// Predict then update with `z`.
    fn step(&mut self, z: &Bound<'_, PyAny>) -> PyResult<()> {
        let z = vec1("z", &extract1("z", z)?, self.model.dim_z())?;
        Ok(self.model.step(&mut self.x, &mut self.p, &z)?)
    }

    /// The state mean, shape `(n,)`.
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.x.as_slice())
    }

    /// The state covariance, shape `(n, n)`.
    #[getter(P)]
    fn p<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let n = self.p.nrows();
        // nalgebra is column-major and P is symmetric-shaped: transpose into row-major order
        let rows: Vec<f64> = self.p.transpose().as_slice().to_vec();
        PyArray1::from_vec(py, rows).reshape([n, n])
    }

    /// Filters a whole `(T, m)` measurement array from the current state; returns the
    /// posterior means `(T, n)` and leaves the filter at the last state.
    fn filter_sequence<'py>(
        &mut self,
        py: Python<'py>,
        zs: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let zs = mat("zs", &extract2("zs", zs)?)?;
        if zs.ncols() != self.model.dim_z() {
            return Err(BindError::Shape {
                arg: "zs",
                expected: format!("(T, {})", self.model.dim_z()),
                got: vec![zs.nrows(), zs.ncols()],
            }
            .into());
        }
        let model = &self.model;
        let (x, p) = (&mut self.x, &mut self.p);
        let n = model.dim_x();
        let rows = zs.nrows();
        let out = py.detach(|| -> Result<Vec<f64>, BindError> {
            let mut out = Vec::with_capacity(rows * n);
            for t in 0..zs.nrows() {
                let z = zs.row(t).transpose();
                model.step(x, p, &z)?;
                out.extend(x.iter().copied());
            }
            Ok(out)
        })?;
        PyArray1::from_vec(py, out).reshape([rows, n])
    }
}

/// The `quarry` Python module.
#[pymodule]
fn quarry(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<KalmanFilter>()?;
    assoc::register(m)?;
    metrics::register(m)?;
    vision::register(m)?;
    Ok(())
}
