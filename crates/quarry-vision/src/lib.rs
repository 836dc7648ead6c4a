//! # quarry-vision
//!
//! Pixel-level building blocks for vision trackers.
//!
//! ```
//! use quarry_core::Plane;
//! let p = Plane::new(4, 3, 0u8);
//! assert_eq!(p.len(), 12);
//! ```

pub mod blur;
mod error;
#[cfg(feature = "io")]
pub mod io;
pub mod matching;
pub mod sift;

pub use blur::{Border, GaussianKernel, gaussian_blur_f32, gaussian_blur_f64};
pub use error::VisionError;
pub use matching::{BruteForceL2, DMatch, DescriptorMatcher, KdTreeMatcher, MatchOptions};
pub use sift::{Sift, SiftDescriptor, SiftParams};
