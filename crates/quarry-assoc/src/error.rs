//! The crate's error type.

use quarry_core::CoreError;
use thiserror::Error;

/// Everything that can go wrong in quarry-assoc.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum AssocError {
    /// A shared error kind (non-finite input, wrong sizes, invalid parameter, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// An assignment problem has no feasible solution (every complete assignment uses a
    /// forbidden pair).
    #[error("assignment problem is infeasible: {0}")]
    Infeasible(String),
}

impl From<AssocError> for CoreError {
    fn from(e: AssocError) -> Self {
        match e {
            AssocError::Core(c) => c,
            AssocError::Infeasible(reason) => CoreError::numerical("assignment", reason),
        }
    }
}

/// Checks that a probability lies in `[lo_open?, 1]`; `open_zero` excludes 0.
pub(crate) fn check_prob(name: &'static str, p: f64, open_zero: bool) -> Result<(), CoreError> {
    let ok = p.is_finite() && p <= 1.0 && if open_zero { p > 0.0 } else { p >= 0.0 };
    if ok {
        Ok(())
    } else {
        Err(CoreError::invalid(
            name,
            format!(
                "{p} is not a probability in {}0, 1]",
                if open_zero { "(" } else { "[" }
            ),
        ))
    }
}
