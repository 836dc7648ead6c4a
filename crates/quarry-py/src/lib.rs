//! Python bindings for quarry, importable as `import quarry` (built with maturin, or by
//! `cargo build -p quarry-py`, which produces `libquarry_py.so` to copy as `quarry.so`).
//!
//! Every binding takes numpy arrays, checks them ([`args`]: dtype, shape, C-contiguity, NaN,
//! empty → `TypeError` / `ValueError` naming the argument), runs quarry's Rust code with the GIL
//! released, and maps every quarry error to a `ValueError` carrying the Rust message. Nothing
//! here panics on user input.
//!
//! - [`filter`]: the stateful `KalmanFilter`, `ekf_predict` / `ekf_update` with the built-in
//!   models, particle weights and resamplers (quarry-filter);
//! - [`assoc`]: chi-square gate, GNN, Hungarian, Murty k-best, PDA / JPDA / JIPDA (quarry-assoc);
//! - [`metrics`]: CLEAR MOT, IDF1, HOTA on arrays and MOTChallenge files, OSPA, GOSPA
//!   (quarry-eval);
//! - [`vision`]: Gaussian blur, regional minima, watershed, SIFT with OpenCV-shaped outputs
//!   (quarry-vision);
//! - [`cloud`]: MeanShift, ICP, the rigid fit, the chi-square background model and the
//!   variance chi-square test (quarry-cloud);
//! - [`trackers`]: the video tracker (spec 004) on a frame array and the laser people tracker
//!   (spec 003) on recorded scans (quarry-trackers).
//!
//! The numerical pieces defined here are usable from Rust as well:
//!
//! ```
//! use nalgebra::{Matrix2, Vector2};
//! use quarry_core::Gaussian;
//! use quarry_filter::{ekf, UpdateForm};
//! use quarry_py::filter::{LinearMeasurement, LinearMotion};
//! let motion = LinearMotion { f: Matrix2::new(1.0, 1.0, 0.0, 1.0), q: Matrix2::identity() * 0.01 };
//! let meas = LinearMeasurement::<2, 1> { h: nalgebra::RowVector2::new(1.0, 0.0), r: nalgebra::Matrix1::new(0.5) };
//! let x0 = Gaussian::try_new(Vector2::zeros(), Matrix2::identity())?;
//! let pred = ekf::predict(&x0, &motion, &(), 1.0)?;
//! let (post, _) = ekf::update(&pred, &meas, &nalgebra::Vector1::new(1.0), UpdateForm::Joseph)?;
//! assert!(post.mean[0] > 0.0 && post.mean[0] < 1.0);
//! # Ok::<(), quarry_filter::FilterError>(())
//! ```

pub mod args;
pub mod assoc;
pub mod cloud;
pub mod filter;
pub mod metrics;
pub mod trackers;
pub mod vision;

use pyo3::prelude::*;

/// The `quarry` Python module.
#[pymodule]
fn quarry(m: &Bound<'_, PyModule>) -> PyResult<()> {
    filter::register(m)?;
    assoc::register(m)?;
    metrics::register(m)?;
    vision::register(m)?;
    cloud::register(m)?;
    trackers::register(m)?;
    Ok(())
}
