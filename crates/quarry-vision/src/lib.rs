//! # quarry-vision
//!
//! Pixel-level building blocks for vision trackers.
//!
//! ```
//! use quarry_core::Plane;
//! let p = Plane::new(4, 3, 0u8);
//! assert_eq!(p.len(), 12);
//! ```

pub mod adjacency;
pub mod blur;
pub mod convert;
mod error;
#[cfg(feature = "io")]
pub mod io;
pub mod mapping;
pub mod minima;
pub mod motion;
pub mod ramp;
#[cfg(feature = "io")]
pub mod render;
pub mod segment;
pub mod watershed;
pub mod matching;
pub mod sift;

pub use adjacency::{RegionAdjacency, RegionStats, region_stats};
pub use blur::{Border, GaussianKernel, gaussian_blur_f32, gaussian_blur_f64};
pub use error::VisionError;
pub use mapping::{LinkKind, RegionMapping};
pub use minima::{Connectivity, Minima, regional_minima};
pub use motion::{MinimumTrajectories, MotionStats, MotionTest};
pub use ramp::add_regular_ramp;
pub use segment::{RampBlurWatershed, SegmentOutput};
pub use watershed::{WatershedOptions, flood, watershed};
pub use matching::{BruteForceL2, DMatch, DescriptorMatcher, KdTreeMatcher, MatchOptions};
pub use sift::{Sift, SiftDescriptor, SiftParams};
