//! Paper 000 in a few lines: RBPF SLAM that also tracks three moving targets with JPDA.
//!
//! Simulates the paper's scenario S0 (seeded), feeds each control step to the tracker through
//! the `MultiTargetTracker` trait, and prints the robot's final error and the target tracks.
//!
//! Run: `cargo run --release --example slamot`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::core::{MultiTargetTracker, Pose2, Stamp};
use quarry::repro::slamot::observation;
use quarry::sim::slamot::{SlamotScenarioConfig, simulate};
use quarry::trackers::slamot::{SlamotConfig, SlamotTracker};

fn main() {
    let scenario = SlamotScenarioConfig::s0();
    let frames = simulate(&scenario, 1).expect("scenario");
    let [x, y, th] = scenario.robot_init;
    let config = SlamotConfig {
        particles: 50,
        ..SlamotConfig::default()
    };
    let mut tracker = SlamotTracker::new(config, Pose2::new(x, y, th), 7).expect("config");

    let mut reports = Vec::new();
    for f in &frames {
        let stamp = Stamp::from_frame(f.k, scenario.dt_control);
        reports = tracker.step(stamp, &observation(f)).expect("step");
    }
    let last = frames.last().expect("frames");
    let est = tracker.pose_estimate();
    let err = (est.x - last.truth.robot.x).hypot(est.y - last.truth.robot.y);
    println!("after {} steps: robot error {err:.3} m", frames.len());
    for r in &reports {
        let [px, py] = r.xy().unwrap_or([f64::NAN; 2]);
        println!("target track {}: ({px:.2}, {py:.2}) {:?}", r.id, r.status);
    }
    for (i, t) in last.truth.targets.iter().enumerate() {
        println!("true target {}: ({:.2}, {:.2})", i + 1, t[0], t[1]);
    }
}
