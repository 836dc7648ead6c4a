//! Paper 003 (people tracking with distributed 2-D laser scanners): the experiments.
//!
//! - [`room`]: the in-process run of the simulated room ([`run_room`], [`run_room_default`]):
//!   clients, simulated network and server, with the ground truth of every frame;
//! - [`calibration`]: `calibration = icp` in the simulator (seeded rough poses, the `calib`
//!   scenario);
//! - [`metrics`]: the paper's success rate (§4) and the standard MOT metrics over the same
//!   frames;
//! - [`recorded`]: scoring a run on the leg-tracker recordings against their labels.
//!
//! ```
//! use quarry_repro::lidar::{evaluate_paper003, run_room_default};
//! use quarry_sim::lidar_room::{Scenario, SpeedBand};
//! use quarry_trackers::lidar_people::{LidarPeopleConfig, gate_of};
//! let sc = Scenario::band(SpeedBand::Slow, 1, 2).with_duration(8.0);
//! let cfg = LidarPeopleConfig::faithful();
//! let run = run_room_default(sc, &cfg, &mut |_| {})?;
//! let window = run.eval_window(quarry_core::TimeUs(6_000_000), 40);
//! let m = evaluate_paper003(&window, &gate_of(&cfg), cfg.min_num_point, cfg.d_match)?;
//! assert_eq!(m.frames, 40);
//! # Ok::<(), quarry_repro::ReproError>(())
//! ```

pub mod calibration;
pub mod metrics;
pub mod recorded;
pub mod room;

pub use calibration::{calibrate_scenario, rough_poses, scanner_infos};
pub use metrics::{
    EvalFrame, LocStats, Paper003Metrics, evaluate_paper003, loc_stats, match_within, paper_success,
};
pub use recorded::{LabelGroupScore, LabelledError, score_label_groups, score_labelled};
pub use room::{
    RoomRun, run_room, run_room_default, run_room_default_observed, run_room_default_until,
};
