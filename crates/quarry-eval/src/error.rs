//! The error type of quarry-eval.

use quarry_core::CoreError;
use thiserror::Error;

/// Everything that can go wrong while scoring a tracker or reading its files.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum EvalError {
    /// A shared error kind (non-finite input, empty input, size mismatch, bad parameter).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A MOTChallenge text line could not be parsed.
    #[error("line {line}: {reason}")]
    Parse {
        /// 1-based line number in the input.
        line: usize,
        /// What was wrong with the line.
        reason: String,
    },
    /// The same object or track id appears twice in one frame.
    #[error("duplicate id {id} in frame {frame} of the {which}")]
    DuplicateId {
        /// `"ground truth"` or `"hypothesis"`.
        which: &'static str,
        /// The frame: its number in a MOTChallenge file (from [`crate::motchallenge`]), or its
        /// 0-based position in the sequence (from [`crate::MotEvaluation::new`]).
        frame: u64,
        /// The repeated id.
        id: i64,
    },
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file involved.
        path: String,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
}

impl EvalError {
    /// Shorthand for a [`EvalError::Parse`] error.
    pub(crate) fn parse(line: usize, reason: impl Into<String>) -> Self {
        Self::Parse {
            line,
            reason: reason.into(),
        }
    }
}
