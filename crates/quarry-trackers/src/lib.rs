//! # quarry-trackers
//!
//! The trackers of the four papers, each a folder that assembles the building-block crates
//! (`mod.rs` with the module docs and re-exports, `config.rs` with the configuration and its
//! presets, `tracker.rs` with the tracker). Every tracker follows one shape:
//! - a configuration implementing [`TrackerConfig`]: named presets ([`PresetName`]), `Default` =
//!   the paper, TOML laid over a preset, one `validate()`;
//! - a tracker implementing [`quarry_core::MultiTargetTracker`] or
//!   [`quarry_core::SingleTargetTracker`], built from a configuration;
//! - one error type, [`TrackerError`], whose variants keep the building blocks' errors as
//!   sources.
//!
//! The crate depends on no simulator and no metrics crate: the experiments that run these
//! trackers on the simulators and score them live in `quarry-repro`, and the readers of real
//! datasets in `quarry-data`.
//!
//! ```
//! use quarry_trackers::lidar_people::{LidarPeopleConfig, Preset};
//! use quarry_trackers::{PresetName, TrackerConfig};
//! for p in Preset::ALL {
//!     LidarPeopleConfig::preset(*p).validate()?; // every preset is valid
//! }
//! let e = LidarPeopleConfig::from_toml("bandwidth = -1", None).unwrap_err();
//! assert!(e.to_string().contains("bandwidth"));
//! # Ok::<(), quarry_trackers::TrackerError>(())
//! ```

mod config;
pub mod cv_jpda;
pub mod ekf_slamot;
mod error;
pub mod lidar_people;
pub mod rgbd_person;
pub mod slamot;
pub mod watershed_sift;

pub use config::{PresetName, TrackerConfig};
pub use error::TrackerError;
