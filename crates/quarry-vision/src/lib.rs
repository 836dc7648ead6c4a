//! # quarry-vision
//!
//! Pixel-level building blocks for vision trackers: f32/f64 images and an OpenCV-exact
//! separable Gaussian blur ([`blur`], [`convert`]), the regular ramp overlay ([`ramp`]), regional
//! minima ([`minima`]), priority-flood (Meyer) watershed without lines
//! ([`watershed`](mod@watershed)), region adjacency and statistics ([`adjacency`]), region mapping
//! between frames ([`mapping`]), minimum trajectories and the moving-point test
//! ([`moving_points`]), SIFT ([`sift`]), descriptor matching ([`matching`]) and the weighted
//! feature pool of spec 004 ([`features::pool`]), and a running median background with its
//! foreground mask ([`background`]). Appearance
//! descriptors of spec 001: hue binning ([`colour`]), Ojala LBP with riu2 / u2 mappings
//! ([`lbp`]), normalised and depth histograms ([`histogram`]), per-pixel weights including the
//! depth band ([`depth_weights`]) and N×N patch histograms ([`patches`]).
//!
//! ```
//! use quarry_core::{Plane, Segmenter};
//! use quarry_vision::{MinimumTrajectories, RampBlurWatershed, RegionAdjacency, RegionMapping};
//!
//! // Two dark discs on a bright background; in the second frame both moved 2 px to the right.
//! let frame = |dx: f64| {
//!     Plane::from_fn(96, 48, |x, y| {
//!         let d = |cx: f64| (f64::from(x) - cx - dx).hypot(f64::from(y) - 24.0);
//!         if d(24.0) < 9.0 || d(70.0) < 9.0 { 30u8 } else { 220 }
//!     })
//! };
//! let segmenter = RampBlurWatershed::new(4.0); // ramp, f64 blur sigma 4, minima, watershed
//! let a = segmenter.segment(&frame(0.0))?;
//! let b = segmenter.segment(&frame(2.0))?;
//! // every pixel has a region, each region grew from exactly one minimum
//! assert!(a.labels.data.iter().all(|&l| l >= 1 && l as usize <= a.n_regions()));
//! let disc = *a.labels.get(24, 24).unwrap();
//! let other = *a.labels.get(70, 24).unwrap();
//! assert_ne!(disc, other);
//! assert!(RegionAdjacency::from_segmentation(&a)?.of(disc).len() >= 1);
//! // the discs' regions persist from one frame to the next
//! let map = RegionMapping::new(&a, &b)?;
//! assert_eq!(map.successor(disc).map(|s| s.0), Some(*b.labels.get(26, 24).unwrap()));
//! let mut traj = MinimumTrajectories::new(10, &a)?;
//! traj.advance(&map, &b)?;
//! assert!(traj.trajectories.iter().any(|t| t.len() == 2));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod adjacency;
pub mod background;
pub mod blur;
pub mod colour;
pub mod convert;
pub mod depth_weights;
mod error;
pub mod features;
pub mod histogram;
#[cfg(feature = "io")]
pub mod io;
pub mod lbp;
pub mod mapping;
pub mod matching;
pub mod minima;
pub mod moving_points;
pub mod multicue;
pub mod patches;
pub mod ramp;
#[cfg(feature = "io")]
pub mod render;
pub mod segment;
pub mod sift;
mod simd;
pub mod watershed;

pub use adjacency::{RegionAdjacency, RegionStats, region_stats};
pub use background::{MedianBackground, MedianBackgroundParams};
pub use blur::{Border, GaussianKernel, gaussian_blur_f32, gaussian_blur_f64};
pub use colour::HueBinner;
pub use depth_weights::{DepthBand, PixelWeight};
pub use error::VisionError;
pub use features::pool::{PoolDescriptor, PoolEntry, PoolParams, PoolUpdateStats, WeightedPool};
pub use histogram::{DepthHistogram, Histogram};
pub use lbp::LbpMapping;
pub use mapping::{LinkKind, RegionMapping};
pub use matching::{BruteForceL2, DMatch, DescriptorMatcher, KdTreeMatcher, MatchOptions};
pub use minima::{Connectivity, Minima, regional_minima};
pub use moving_points::{MinimumTrajectories, MotionStats, MotionTest};
pub use multicue::{
    CandidateScore, PatchDescriptor, PatchModelConfig, PatchMultiCueModel, RgbdFeatures, RgbdFrame,
};
pub use patches::{PatchGrid, PatchHistograms, patch_histograms};
pub use ramp::add_regular_ramp;
pub use segment::{RampBlurWatershed, SegmentOutput};
pub use sift::{Sift, SiftDescriptor, SiftParams};
pub use watershed::{WatershedOptions, flood, watershed};
