//! RGB-D person tracking on a mobile robot with a patch multi-cue model and the MEKF (spec 001).
//!
//! Per frame (spec §2.11): MEKF predict with the odometry → depth gate and projected prediction
//! → candidate grid G1 around the previous output, the MEKF candidate and its local grid G2 →
//! features over the union of candidates → describe and score every candidate → tiered
//! selection T1 / T2a / T2b / T3 → occlusion state → MEKF update, template update (eq. 12) and
//! scale (A2) only in the states that allow it. With no detection the projected prediction is
//! the output (`FullOcclusion`, then `Lost` after `lost_after` frames).
//!
//! | file | contents |
//! |---|---|
//! | `config.rs` | [`RgbdPersonConfig`], [`ScaleRule`], the presets [`Preset`] |
//! | `tracker.rs` | [`RgbdPersonTracker`], [`TrackOutput`] |
//! | `select.rs` | the tiered selection, [`DetectionTier`] |
//! | `occlusion.rs` | [`OcclusionState`], the state rule and the learning gate |
//!
//! The runs on the synthetic scenarios S1-S6 (per-frame records, the §5.4 measures, the
//! template drift score) are in `quarry_repro::rgbd`.
//!
//! ```
//! use quarry_core::{BBox, EgoMotion, Plane, SingleTargetTracker, Stamp};
//! use quarry_trackers::rgbd_person::{OcclusionState, Preset, RgbdPersonConfig, RgbdPersonTracker};
//! use quarry_trackers::TrackerConfig;
//! use quarry_vision::RgbdFrame;
//!
//! // a 96x72 frame: a person in three colour bands 2 m away, left edge at x0, before a wall 4 m away
//! fn frame(x0: u32) -> Result<RgbdFrame, Box<dyn std::error::Error>> {
//!     let (w, h) = (96u32, 72u32);
//!     let person = |x: u32, y: u32| (x0..x0 + 24).contains(&x) && (12..60).contains(&y);
//!     let (mut rgb, mut depth) = (Vec::new(), Vec::new());
//!     for y in 0..h {
//!         for x in 0..w {
//!             let c = if person(x, y) {
//!                 let band = [[40u8, 90, 200], [220, 180, 60], [200, 40, 60]][((x - x0) / 8) as usize];
//!                 band.map(|v| if (y / 6) % 2 == 0 { v } else { v / 2 })
//!             } else {
//!                 let g = (100 + (x * 7 + y * 13) % 50) as u8;
//!                 [g, g, g]
//!             };
//!             rgb.extend_from_slice(&c);
//!             depth.push(if person(x, y) { 2.0f32 } else { 4.0 });
//!         }
//!     }
//!     Ok(RgbdFrame::new(w, h, rgb, Plane::from_vec(w, h, depth)?, EgoMotion::None)?)
//! }
//!
//! // the paper's configuration with the camera of this small image
//! let mut cfg = RgbdPersonConfig::preset(Preset::Paper);
//! cfg.intrinsics.width = 96;
//! cfg.intrinsics.height = 72;
//! cfg.intrinsics.cx = 47.5;
//! cfg.intrinsics.cy = 35.5;
//! let mut tr = RgbdPersonTracker::new(cfg)?;
//! tr.init(Stamp::from_frame(0, 1.0 / 30.0), &frame(36)?, BBox::from_ltwh(36.0, 12.0, 24.0, 48.0))?;
//! // the person steps 2 px to the right: the box follows (centre x 48 -> 50)
//! let out = tr.step(Stamp::from_frame(1, 1.0 / 30.0), &frame(38)?)?;
//! assert!(out.confirmed);
//! assert_eq!(out.state, OcclusionState::Normal);
//! assert!((out.bbox.unwrap().cx - 50.0).abs() <= 3.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Choices where the spec leaves one are listed in `docs/rgbd-person.md`.

mod config;
mod occlusion;
mod select;
mod tracker;

pub use config::{MAX_IMAGE_SIDE, Preset, RgbdPersonConfig, ScaleRule};
pub use occlusion::OcclusionState;
pub use select::DetectionTier;
pub use tracker::{RgbdPersonTracker, TrackOutput};
