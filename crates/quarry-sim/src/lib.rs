//! # quarry-sim
//!
//! Seeded, deterministic scenario generators with ground truth, one per paper, and readers for
//! recorded datasets. Every generator takes its seed explicitly: the same seed gives the same
//! scenario, bit for bit.
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

pub use error::SimError;
