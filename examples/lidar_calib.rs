//! Extrinsic calibration of the three scanners of paper 003 from their backgrounds
//! (`calibration = icp`, spec 003 §2.3): the spec's `calib` scenario (empty room, 10 s), rough
//! poses drawn up to 0.3 m / 10° from the seed, trimmed ICP of the long-term backgrounds `b_n`
//! against the reference scanner A, then the recovered poses and their errors.
//!
//! Run: `cargo run --release --example lidar_calib`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::repro::lidar::calibrate_scenario;
use quarry::sim::lidar_room::Scenario;
use quarry::trackers::lidar_people::{Calibration, LidarPeopleConfig};

fn main() {
    let cfg = LidarPeopleConfig {
        calibration: Calibration::Icp,
        ..LidarPeopleConfig::faithful()
    };
    let report = calibrate_scenario(Scenario::calib(1), &cfg).expect("calibration");
    for s in &report.scanners {
        println!(
            "{}: rough {:.3} m / {:.2}° off -> calibrated ({:.4}, {:.4}, {:.3}°), {:.4} m / {:.4}° off",
            s.name,
            s.rough_pos_error_m,
            s.rough_rot_error_deg,
            s.pose.x,
            s.pose.y,
            s.pose.theta.to_degrees(),
            s.pos_error_m,
            s.rot_error_deg
        );
    }
    // `run_room_default` with the same configuration calibrates at the end of the warm-up and
    // then tracks with the calibrated poses (`RoomRun::calibration` holds this report).
}
