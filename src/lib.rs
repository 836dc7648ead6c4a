//! # quarry
//!
//! Multi-target tracking for robotics and vision, as small composable crates. This facade
//! re-exports them under short names:
//!
//! | module | crate | contents |
//! |---|---|---|
//! | [`core`] | quarry-core | shared types and plugin traits |
//! | [`filter`] | quarry-filter | KF / EKF / MEKF, particle filters, Rao-Blackwellized maps |
//! | [`assoc`] | quarry-assoc | gates, GNN, PDA, JPDA, JIPDA, track management |
//! | [`cloud`] | quarry-cloud | scans, kd-tree, ICP, MeanShift, background models, fusion |
//! | [`vision`] | quarry-vision | blur, watershed, region mapping, SIFT, histograms |
//! | [`sim`] | quarry-sim | seeded scenario generators with ground truth |
//! | [`eval`] | quarry-eval | RMSE/NEES, CLEAR MOT, IDF1, HOTA, OSPA/GOSPA |
//! | [`trackers`] | quarry-trackers | the four papers' trackers |
//! | [`net`] | quarry-net | networked lidar tracker: wire format, clock sync, frame assembly, transports (in-process, zenoh), nodes, server |
//! | [`data`] | quarry-data | readers of real recordings (MRCLAM, recorded laser scans) |
//! | [`repro`] | quarry-repro | the papers' experiments: trackers on the simulators and on recordings, scored |
//!
//! ```
//! use quarry::core::{Pose2, Point2};
//! let p = Pose2::new(0.0, 0.0, 0.0).apply(&Point2::new(1.0, 2.0));
//! assert_eq!(p, Point2::new(1.0, 2.0));
//! ```

pub use quarry_assoc as assoc;
pub use quarry_cloud as cloud;
pub use quarry_core as core;
pub use quarry_data as data;
pub use quarry_eval as eval;
pub use quarry_filter as filter;
pub use quarry_net as net;
pub use quarry_repro as repro;
pub use quarry_sim as sim;
pub use quarry_trackers as trackers;
pub use quarry_vision as vision;
