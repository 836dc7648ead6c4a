//! # quarry-sim
//!
//! Seeded, deterministic scenario generators with ground truth, one per paper (the readers of
//! real recordings are in quarry-data). Every generator takes its seed explicitly: the same seed
//! gives the same scenario, bit for bit.
//!
//! | module | paper | what it generates |
//! |---|---|---|
//! | [`slamot`] | 000 | a robot with odometry and range-bearing sensing among landmarks and moving targets |
//! | [`rgbd`] | 001 | ray-cast RGB-D sequences S1-S6 with a person to follow, on a mobile robot |
//! | [`lidar_room`] | 003 | a room with people and distributed 2-D laser scanners |
//! | [`walkers`] | 004 | the grey video `walkers-v1` (+ `-ab`, `-empty`): dark textured walkers over value noise, MOT16 ground truth and events |
//!
//! ```
//! use quarry_core::rng::seeded;
//! use rand::Rng;
//! let mut a = seeded(1);
//! let mut b = seeded(1);
//! assert_eq!(a.random::<u64>(), b.random::<u64>());
//! ```

mod error;
pub mod lidar_room;
pub mod rgbd;
pub mod slamot;
pub mod walkers;

pub use error::SimError;
