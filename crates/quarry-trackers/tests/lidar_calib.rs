//! `calibration = icp` (spec 003 §2.3) on the simulated room: property 7 of §8 on the `calib`
//! scenario with noisy scans, tracking with calibrated poses, and the clear error of a rough pose
//! far off.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry_sim::lidar_room::Scenario;
use quarry_trackers::lidar_people::{Calibration, LidarPeopleConfig, calibrate_scenario};

fn icp() -> LidarPeopleConfig {
    LidarPeopleConfig {
        calibration: Calibration::Icp,
        ..LidarPeopleConfig::default()
    }
}

#[test]
fn calib_scenario_recovers_every_pose_to_2_cm_and_0_3_degrees() {
    for seed in 1..=8 {
        let rep = calibrate_scenario(Scenario::calib(seed), &icp()).unwrap();
        for s in &rep.scanners {
            eprintln!(
                "seed {seed} {}: rough {:.3} m {:.2} deg -> {:.4} m {:.4} deg (overlap {:.3}, rms {:.4}, {} pts)",
                s.name,
                s.rough_pos_error_m,
                s.rough_rot_error_deg,
                s.pos_error_m,
                s.rot_error_deg,
                s.overlap,
                s.rms_m,
                s.background_points
            );
        }
        assert!(rep.max_pos_error_m <= 0.02, "seed {seed}: {rep:?}");
        assert!(rep.max_rot_error_deg <= 0.3, "seed {seed}: {rep:?}");
    }
}
