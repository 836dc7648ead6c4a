//! The crate's error type.

use quarry_core::CoreError;
use thiserror::Error;

/// Errors of quarry-vision.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum VisionError {
    /// A shared error kind (non-finite input, bad parameter, ...).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// An image with no pixels, or too small for the operation.
    #[error("image too small for {what}: {width}x{height} (need at least {min}x{min})")]
    EmptyImage {
        /// The operation.
        what: &'static str,
        /// Width given.
        width: u32,
        /// Height given.
        height: u32,
        /// Minimal side length.
        min: u32,
    },
    /// Two images that must have the same size do not.
    #[error("size mismatch in {what}: {a:?} vs {b:?}")]
    SizeMismatch {
        /// The operation.
        what: &'static str,
        /// First size (width, height).
        a: (u32, u32),
        /// Second size (width, height).
        b: (u32, u32),
    },
    /// A blur sigma that is not finite and positive.
    #[error("invalid sigma {0}: must be finite and > 0")]
    InvalidSigma(f64),
    /// A blur sigma whose kernel would be wider than the largest supported one.
    #[error(
        "sigma {sigma} is too large: at most {max} pixels (the kernel has round(8 sigma + 1) taps)"
    )]
    SigmaTooLarge {
        /// The sigma given.
        sigma: f64,
        /// The largest accepted sigma.
        max: f64,
    },
    /// A NaN or infinite pixel.
    #[error("non-finite pixel in {0}")]
    NonFinite(&'static str),
    /// An image larger than the documented limit.
    #[error("image too large for {what}: {width}x{height} (limit {limit} pixels)")]
    TooLarge {
        /// The operation.
        what: &'static str,
        /// Width given.
        width: u32,
        /// Height given.
        height: u32,
        /// Maximal number of pixels.
        limit: u64,
    },
    /// An image file that could not be read or written.
    #[error("image file {path}: {reason}")]
    Io {
        /// The path.
        path: String,
        /// What went wrong.
        reason: String,
    },
}
