//! # quarry-repro
//!
//! The experiments of the four papers, kept apart from the trackers so that a user of a
//! tracker does not pull in the simulators or the metrics: scenario drivers that run a
//! `quarry_trackers` tracker on a `quarry_sim` scenario, the runs on real recordings read by
//! `quarry-data`, and the scoring glue to `quarry-eval` and to each paper's own measures. The
//! CLI (`quarry slamot`, `quarry lidar`, `quarry rgbd`, `quarry video sim`, `quarry demo`), the benches and the docs
//! figures all come from here.
//!
//! | module | paper | what it runs |
//! |---|---|---|
//! | [`slamot`] | 000 | the simulated S0/S1 runs (spec §4), the MRCLAM runs |
//! | [`rgbd`] | 001 | the scenarios S1-S6 of the RGB-D simulator, with per-frame records |
//! | [`lidar`] | 003 | the simulated room (clients, network, server), calibration, recorded scans |
//! | [`video`] | 004 | the watershed + SIFT tracker on `walkers-v1`: checks E1-E7, the threshold grid, pool sizes |
//!
//! ```
//! use quarry_repro::slamot::run_simulated;
//! use quarry_sim::slamot::SlamotScenarioConfig;
//! use quarry_trackers::slamot::SlamotConfig;
//! let mut scen = SlamotScenarioConfig::s0();
//! scen.duration = 5.0;
//! let cfg = SlamotConfig { particles: 10, ..SlamotConfig::default() };
//! let run = run_simulated(&cfg, &scen, 1, 2)?;
//! assert!(run.robot_err.iter().all(|e| *e < 2.0));
//! # Ok::<(), quarry_repro::ReproError>(())
//! ```

mod error;
pub mod lidar;
pub mod rgbd;
pub mod slamot;
pub mod video;

pub use error::{ReproError, Result};
