//! Fully automatic multi-object video tracking with watershed segmentation and weighted SIFT
//! feature pools (spec 004; Hu, Gu, Wang, Zou & Jin 2012).
//!
//! Per grey frame: a regular ramp and a float Gaussian blur, regional minima and a Meyer
//! watershed give regions with one minimum each; regions are mapped onto the previous frame's
//! through their minima (bidirectional match, merge, split); chains of bidirectional matches
//! give 10-frame trajectories whose regular displacement marks *moving points*, and a moving
//! point no target owns starts a target. A target is a list of regions, its centre the mean of
//! their minima (eq. 8), its box a fixed `box_w × box_h` around it, and its identity a weighted
//! pool of SIFT descriptors (eqs. 9-11) that decides splits, absorptions, occlusions and
//! separations.
//!
//! The `robust` profile adds a running median background (`quarry_vision::MedianBackground`):
//! each reported box is fitted to the target's foreground pixels, targets without foreground
//! are not reported, uncovered foreground blobs start targets, and background regions skip
//! the SIFT ownership test (docs/video-tracker.md has what each bought on PETS09-S2L1).
//!
//! | file | holds |
//! |---|---|
//! | `config.rs` | [`WatershedSiftConfig`] (every parameter of §3 with its source), [`Profile`], [`Polarity`] |
//! | `frontend.rs` | [`MotionFrontEnd`]: segmentation, mapping, trajectories, moving points (also `quarry motion`) |
//! | `tracker.rs` | [`WatershedSiftTracker`], [`Target`], [`RegionRef`], [`Provenance`], [`FrameDiagnostics`] |
//!
//! ```
//! use quarry_core::{MultiTargetTracker, Plane, Stamp};
//! use quarry_trackers::watershed_sift::{WatershedSiftConfig, WatershedSiftTracker};
//! let cfg = WatershedSiftConfig::robust().with_person_size(12.0, 30.0);
//! let mut tracker = WatershedSiftTracker::new(cfg)?;
//! // a dark blob walking right on a textured background
//! for k in 0..14u64 {
//!     let cx = 20.0 + 2.0 * k as f64;
//!     let frame = Plane::from_fn(96, 64, |x, y| {
//!         let (fx, fy) = (f64::from(x), f64::from(y));
//!         let bg = 170.0 + 20.0 * ((fx * 0.3).sin() * (fy * 0.23).cos());
//!         let inside = ((fx - cx) / 5.0).powi(2) + ((fy - 32.0) / 13.0).powi(2) <= 1.0;
//!         (if inside { 60.0 + 15.0 * ((fx + fy) * 0.9).sin() } else { bg }) as u8
//!     });
//!     let reports = tracker.step(Stamp::from_frame(k, 0.04), &frame)?;
//!     assert!(reports.len() <= 2);
//! }
//! # Ok::<(), quarry_trackers::TrackerError>(())
//! ```

mod config;
mod frontend;
mod tracker;

pub use config::{
    MAX_BOX_SIDE, MAX_FRAMES_RULE, MAX_N, MAX_SIGMA, Polarity, Profile, WatershedSiftConfig,
};
pub use frontend::MotionFrontEnd;
pub use tracker::{
    FrameDiagnostics, Provenance, RegionRef, RoiFeatures, StageTimes, Target, TargetDiagnostics,
    WatershedSiftTracker, mapping_counts,
};
