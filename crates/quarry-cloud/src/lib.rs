//! # quarry-cloud
//!
//! 2-D point clouds for laser people tracking (spec 003): polar scans, a kd-tree index,
//! the chi-square background model, MeanShift, ICP and scanner calibration. (The
//! time-synchronised fusion of scans into frames, with its wire format, is network code and
//! lives in quarry-net's sans-IO `proto` module; the recorded-scan CSV reader is in quarry-data.)
//!
//! | module | contents |
//! |---|---|
//! | [`scan`] | beam geometry helpers, [`scan::BeamTable`] (polar → Cartesian), range validity |
//! | [`kd`] | [`kd::KdIndex`]: kiddo `ImmutableKdTree` with de-duplication and a removal mask |
//! | [`background`] | [`background::ChiSquareBackground`] (eqs. 3–6, region constraint, long-term background) |
//! | [`cluster`] | [`cluster::MeanShift`] (flat / Gaussian, bin or all-point seeds, deterministic) |
//! | [`icp`] | [`icp::rigid_2d`] (closed form) and [`icp::Icp2d`] (trimmed point-to-point ICP) |
//! | [`contour`] | [`contour::EllipseModel`], the human contour model of §2.6 |
//! | [`legs`] | [`legs::LegDetector`]: leg clusters at leg height, paired into people (single-leg fallback) |
//! | [`calib`] | scanner extrinsics from static backgrounds, or from configured poses |
//!
//! Every public function that takes data returns `Result<_, CloudError>` (the quarry-core trait
//! implementations return `CoreError`); nothing panics on bad input.
//!
//! ```
//! use quarry_cloud::{cluster::MeanShift, icp::Icp2d};
//! use quarry_core::{Clusterer, Point2, Pose2, Registration2};
//!
//! // two blobs -> two clusters
//! let pts: Vec<Point2> = (0..20)
//!     .map(|i| Point2::new(f64::from(i % 5) * 0.02, f64::from(i / 5) * 0.02 + if i % 2 == 0 { 0.0 } else { 3.0 }))
//!     .collect();
//! let c = MeanShift::default().cluster(&pts)?;
//! assert_eq!(c.modes.len(), 2);
//!
//! // ICP recovers a rigid motion of a contour (the spec's 1 cm RMS stop disabled here)
//! let model: Vec<Point2> = (0..36).map(|k| {
//!     let a = f64::from(k) * 10f64.to_radians();
//!     Point2::new(0.22 * a.cos(), 0.13 * a.sin())
//! }).collect();
//! let truth = Pose2::new(1.0, 2.0, 0.2);
//! let data: Vec<Point2> = model.iter().map(|m| truth.apply(m)).collect();
//! let icp = Icp2d { rms_stop: 0.0, delta_stop: 1e-12, max_iter: 500, ..Icp2d::contour() };
//! let r = icp.register(&model, &data, Pose2::new(0.97, 2.02, 0.15))?;
//! assert!((r.pose.x - 1.0).abs() < 1e-6 && (r.pose.theta - 0.2).abs() < 1e-6);
//! # Ok::<(), quarry_core::CoreError>(())
//! ```

// `!(x > 0.0)` is the NaN-rejecting form of a positivity check, used on purpose throughout
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// per-beam loops index several parallel arrays by beam number; the index is the clearer form
#![allow(clippy::needless_range_loop)]

pub mod background;
pub mod calib;
pub mod cluster;
pub mod contour;
pub mod error;
pub mod icp;
pub mod kd;
pub mod legs;
pub mod scan;

pub use error::CloudError;
pub use quarry_core::{Point2, Point3};
