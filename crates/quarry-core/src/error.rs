//! The shared error kinds.

use thiserror::Error;

/// The error kinds shared by every quarry crate.
///
/// Each other crate has one `thiserror` enum that wraps this one (`FilterError`, `AssocError`, ...).
/// Every variant names *what* was wrong, so a message reads like "non-finite value in measurement z".
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum CoreError {
    /// A NaN or infinite number where a finite one is required.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Which input held the value.
        what: &'static str,
    },
    /// A matrix that must be symmetric positive definite is not.
    #[error("{what} is not symmetric positive definite")]
    NotPositiveDefinite {
        /// Which matrix.
        what: &'static str,
    },
    /// Sizes that must agree do not.
    #[error("dimension mismatch in {what}: expected {expected}, got {got}")]
    DimensionMismatch {
        /// Which input.
        what: &'static str,
        /// The size that was required.
        expected: usize,
        /// The size that was given.
        got: usize,
    },
    /// An input that must hold at least one element is empty.
    #[error("empty input: {what}")]
    Empty {
        /// Which input.
        what: &'static str,
    },
    /// A parameter is outside its valid range.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
        /// Why it is invalid, including the valid range.
        reason: String,
    },
    /// A numerical procedure failed (all weights zero, a solve that did not converge, ...).
    #[error("numerical failure in {what}: {reason}")]
    Numerical {
        /// Which computation.
        what: &'static str,
        /// What happened.
        reason: String,
    },
}

impl CoreError {
    /// Shorthand for [`CoreError::InvalidParameter`].
    pub fn invalid(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name,
            reason: reason.into(),
        }
    }

    /// Shorthand for [`CoreError::Numerical`].
    pub fn numerical(what: &'static str, reason: impl Into<String>) -> Self {
        Self::Numerical {
            what,
            reason: reason.into(),
        }
    }
}

/// Returns [`CoreError::NonFinite`] unless every value is finite.
pub fn ensure_finite<'a, I>(values: I, what: &'static str) -> Result<(), CoreError>
where
    I: IntoIterator<Item = &'a f64>,
{
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(CoreError::NonFinite { what })
    }
}

/// Returns [`CoreError::DimensionMismatch`] unless `got == expected`.
pub fn ensure_len(got: usize, expected: usize, what: &'static str) -> Result<(), CoreError> {
    if got == expected {
        Ok(())
    } else {
        Err(CoreError::DimensionMismatch {
            what,
            expected,
            got,
        })
    }
}
