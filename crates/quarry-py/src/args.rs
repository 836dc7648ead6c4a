//! Argument checks shared by every binding: a numpy array of the right dtype, number of
//! dimensions, sizes, memory layout and values, or a Python exception naming the argument.
//!
//! Wrong type or dtype → `TypeError`; wrong shape, empty, non-contiguous, NaN / infinity →
//! `ValueError`. Arrays must be C-contiguous: the bindings read them in place (no hidden
//! copy), so a strided view is refused with a message saying how to fix it.

use numpy::{
    Element, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// Which non-finite values an argument may hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Values {
    /// Finite values only.
    Finite,
    /// Finite values or `-inf` (log-likelihoods: `-inf` = outside the gate).
    FiniteOrNegInf,
    /// Finite values or `+inf` (assignment costs: `+inf` = forbidden pair).
    FiniteOrPosInf,
    /// Finite values or NaN (depth images: NaN = no reading).
    FiniteOrNan,
}

/// A value type the checks understand (integers are always finite).
pub trait Checked: Element + Copy {
    /// The value as f64, for the finiteness checks.
    fn as_f64(self) -> f64;
    /// Name of the numpy dtype, for messages.
    const DTYPE: &'static str;
}

macro_rules! checked {
    ($($t:ty => $name:literal),*) => {$(
        impl Checked for $t {
            #[allow(clippy::cast_lossless, clippy::cast_precision_loss)]
            fn as_f64(self) -> f64 { self as f64 }
            const DTYPE: &'static str = $name;
        }
    )*};
}
checked!(f64 => "float64", f32 => "float32", u8 => "uint8", i32 => "int32", i64 => "int64");

/// One expected dimension: a fixed size or any size.
pub type Dim = Option<usize>;

/// Formats a shape the numpy way: `(3,)`, `(2, 4)`.
pub fn fmt_shape(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// A `ValueError` starting with the argument's name.
pub fn value_error(name: &str, what: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{name}: {what}"))
}

/// Reads `ob` as a C-contiguous numpy array of `T` with `dims.len()` dimensions, each of the
/// given size where one is fixed (`expected` describes the shape in words for messages, e.g.
/// `"(n, 2)"`), non-empty unless `allow_empty`, and with [`Values`] checked for floats.
///
/// # Errors
/// `TypeError` for a non-array or another dtype, `ValueError` for the rest; both name `name`.
pub fn array<'py, T: Checked>(
    ob: &Bound<'py, PyAny>,
    name: &str,
    expected: &str,
    dims: &[Dim],
    allow_empty: bool,
    values: Values,
) -> PyResult<PyReadonlyArrayDyn<'py, T>> {
    let py = ob.py();
    let untyped = ob.cast::<PyUntypedArray>().map_err(|_| {
        let ty = ob
            .get_type()
            .name()
            .map_or_else(|_| "?".to_string(), |n| n.to_string());
        PyTypeError::new_err(format!(
            "{name}: expected a numpy.ndarray of {}, got {ty}",
            T::DTYPE
        ))
    })?;
    let dtype = untyped.dtype();
    if !dtype.is_equiv_to(&numpy::dtype::<T>(py)) {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected dtype {}, got {} (convert with .astype(np.{}))",
            T::DTYPE,
            dtype
                .str()
                .map_or_else(|_| "?".to_string(), |s| s.to_string()),
            T::DTYPE
        )));
    }
    let shape = untyped.shape().to_vec();
    let shape_ok = shape.len() == dims.len()
        && shape
            .iter()
            .zip(dims)
            .all(|(&s, d)| d.is_none_or(|d| d == s));
    if !shape_ok {
        return Err(value_error(
            name,
            format!("expected shape {expected}, got {}", fmt_shape(&shape)),
        ));
    }
    if !allow_empty && shape.contains(&0) {
        return Err(value_error(
            name,
            format!(
                "is empty (shape {}), expected {expected}",
                fmt_shape(&shape)
            ),
        ));
    }
    if !untyped.is_c_contiguous() {
        return Err(value_error(
            name,
            "array is not C-contiguous (pass np.ascontiguousarray(...))",
        ));
    }
    let typed = untyped
        .cast::<PyArrayDyn<T>>()
        .map_err(|_| PyTypeError::new_err(format!("{name}: expected dtype {}", T::DTYPE)))?;
    let ro = typed
        .try_readonly()
        .map_err(|e| value_error(name, format!("cannot borrow the array ({e})")))?;
    let slice = ro
        .as_slice()
        .map_err(|e| value_error(name, format!("array is not contiguous ({e})")))?;
    check_values(slice, name, values)?;
    Ok(ro)
}

/// Checks the values of a slice against [`Values`].
///
/// # Errors
/// `ValueError` naming `name` and the first offending index.
pub fn check_values<T: Checked>(slice: &[T], name: &str, values: Values) -> PyResult<()> {
    let ok = |v: f64| {
        v.is_finite()
            | match values {
                Values::Finite => false,
                Values::FiniteOrNegInf => v == f64::NEG_INFINITY,
                Values::FiniteOrPosInf => v == f64::INFINITY,
                Values::FiniteOrNan => v.is_nan(),
            }
    };
    // a branch-free sweep first (vectorised: this runs over every pixel of an image), the
    // index of the culprit only on failure
    if slice.iter().fold(true, |acc, &v| acc & ok(v.as_f64())) {
        return Ok(());
    }
    let (i, v) = slice
        .iter()
        .enumerate()
        .map(|(i, &v)| (i, v.as_f64()))
        .find(|&(_, v)| !ok(v))
        .unwrap_or((0, f64::NAN));
    let allowed = match values {
        Values::Finite => "",
        Values::FiniteOrNegInf => " (only -inf is allowed)",
        Values::FiniteOrPosInf => " (only +inf is allowed)",
        Values::FiniteOrNan => " (only NaN is allowed)",
    };
    Err(value_error(
        name,
        format!("contains {v} at flat index {i}{allowed}"),
    ))
}

/// The contiguous data of an array accepted by [`array()`].
pub fn data<'a, T: Checked>(a: &'a PyReadonlyArrayDyn<'_, T>) -> &'a [T] {
    // `array` checked C-contiguity, so this cannot fail; an empty slice is the safe fallback.
    a.as_slice().unwrap_or(&[])
}

/// Checks a scalar parameter is finite.
///
/// # Errors
/// `ValueError` naming `name`.
pub fn finite(name: &str, v: f64) -> PyResult<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(value_error(name, format!("must be finite, got {v}")))
    }
}

/// Most cells of a matrix a binding builds from smaller arguments (2²⁸ f64 = 2 GiB): beyond it
/// the allocation would fail and abort the interpreter instead of raising.
pub const MAX_CELLS: usize = 1 << 28;

/// Checks that a derived `rows × cols` matrix stays within [`MAX_CELLS`].
///
/// # Errors
/// `ValueError` naming `name` (the argument whose size decides).
pub fn check_cells(name: &str, what: &str, rows: usize, cols: usize) -> PyResult<()> {
    if rows.saturating_mul(cols) > MAX_CELLS {
        return Err(value_error(
            name,
            format!("{what} of {rows} x {cols} cells exceeds the {MAX_CELLS}-cell limit"),
        ));
    }
    Ok(())
}

/// A finite pose `(x, y, theta)` argument.
///
/// # Errors
/// `ValueError` naming `name` when a component is NaN or infinite.
pub fn pose(name: &str, p: (f64, f64, f64)) -> PyResult<quarry_core::Pose2> {
    Ok(quarry_core::Pose2::new(
        finite(name, p.0)?,
        finite(name, p.1)?,
        finite(name, p.2)?,
    ))
}

/// Maps an error to a `ValueError` with its Rust message, prefixed by the call name.
pub fn map_err<E: std::fmt::Display>(call: &'static str) -> impl Fn(E) -> PyErr {
    move |e| PyValueError::new_err(format!("{call}: {e}"))
}
