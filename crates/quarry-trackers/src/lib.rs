//! # quarry-trackers
//!
//! The trackers of the four papers, each a module that assembles the building-block crates.
//!
//! ```
//! use quarry_trackers::TrackerError;
//! let e = TrackerError::Config("particles must be > 0".into());
//! assert!(e.to_string().contains("particles"));
//! ```

/// EKF-SLAMOT: the joint-EKF baseline of paper 000 (its reference [8]).
pub mod ekf_slamot;
mod error;
/// Stand-alone CV-Kalman + JPDA/JIPDA multi-target tracker (quarry-assoc's reference tracker).
pub mod jpda;
pub mod lidar_people;
pub mod rgbd_person;
pub mod slamot;

pub use error::TrackerError;
