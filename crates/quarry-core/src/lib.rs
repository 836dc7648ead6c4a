//! # quarry-core
//!
//! The shared vocabulary of quarry: the types every crate speaks ([`Gaussian`], [`Pose2`],
//! [`Stamp`], [`TrackId`], [`BBox`], [`Plane`], [`TrackReport`]) and the plugin traits the
//! building-block crates implement ([`MotionModel`], [`MeasurementModel`], [`Gate`],
//! [`Associator`], [`Resampler`], [`LandmarkStore`], [`Clusterer`], [`Registration2`],
//! [`BackgroundModel`], [`Segmenter`], [`FeatureDetector`], [`DescriptorExtractor`],
//! [`AppearanceModel`], [`MultiTargetTracker`], [`SingleTargetTracker`]). No algorithms live
//! here: a third party implements a trait and plugs into any quarry tracker.
//!
//! ```
//! use nalgebra::{Matrix2, Vector2};
//! use quarry_core::{Gaussian, Pose2, Point2, TrackId, TrackReport, TrackStatus, Stamp};
//!
//! // A validated Gaussian: symmetric positive definite or an error.
//! let g = Gaussian::try_new(Vector2::new(1.0, 2.0), Matrix2::identity() * 0.5)?;
//! assert!(g.mahalanobis2(&Vector2::new(1.0, 2.0))? < 1e-12);
//!
//! // SE(2) poses compose, invert and map points.
//! let robot = Pose2::new(1.0, 0.0, std::f64::consts::FRAC_PI_2);
//! let p = robot.apply(&Point2::new(1.0, 0.0));
//! assert!((p - Point2::new(1.0, 1.0)).norm() < 1e-12);
//!
//! // Every tracker reports the same record.
//! let r = TrackReport::new(Stamp::from_frame(3, 0.1), TrackId(1), TrackStatus::Confirmed);
//! assert_eq!(r.stamp.frame.0, 3);
//! # Ok::<(), quarry_core::CoreError>(())
//! ```
//!
//! ## Features
//!
//! - `serde` (default): `serde::Serialize` / `serde::Deserialize` on the vocabulary types, with
//!   nalgebra's `serde-serialize` for the vectors and matrices they hold.
//! - `rng` (default): the `rng` module, a seeded xoshiro256++ generator (pulls in
//!   `rand_xoshiro`). Without it, pass any `rand_core::RngCore` where quarry takes a generator.
//! - `image`: `From` conversions between [`Plane`] and `image` buffers.
//!
//! `default-features = false` leaves the types, traits and checks only (nalgebra, thiserror,
//! rand_core).

mod appearance;
mod assoc;
mod cloud;
mod error;
mod gaussian;
mod geometry;
mod models;
mod particles;
mod plane;
mod report;
#[cfg(feature = "rng")]
pub mod rng;
pub mod stats;
mod time;
mod tracker;
mod vision;

pub use appearance::{AppearanceModel, CameraMount, EgoMotion, PinholeIntrinsics};
pub use assoc::{Association, Associator, LikelihoodMatrix, TrackPrior};
pub use cloud::{
    BackgroundModel, BeamLabel, Clusterer, Clustering, Detection2, PolarScan, RegResult,
    Registration2, ScanGeometry,
};
pub use error::{CoreError, ensure_finite, ensure_len};
pub use gaussian::{Gaussian, SYMMETRY_TOL, validate_covariance};
pub use geometry::{BBox, Point2, Point3, Pose2, Pose3, wrap_angle};
pub use models::{Gate, InverseMeasurement, MeasurementModel, MotionModel, SampledMotion};
pub use particles::{LandmarkStore, Resampler};
pub use plane::Plane;
pub use report::{StateEstimate, StateLayout, TrackFlags, TrackReport, TrackStatus};
pub use time::{FrameIndex, LandmarkId, SensorId, Stamp, TimeUs, TrackId};
pub use tracker::{MultiTargetTracker, SingleTargetTracker};
pub use vision::{
    DescriptorExtractor, FeatureDetector, FeatureExtractor, Keypoint, MinimumInfo, Segmentation,
    Segmenter,
};

/// Re-exported so downstream crates use the same nalgebra version.
pub use nalgebra;
