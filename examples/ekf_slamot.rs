//! The paper's baseline (its reference [8]): one joint EKF over robot, landmarks and targets,
//! against the RBPF on the stress scenario S1 (missed detections and clutter, two-point target
//! initiation).
//!
//! Run: `cargo run --release --example ekf_slamot`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::repro::slamot::{filter_seed, mean_var, run_simulated, run_simulated_ekf};
use quarry::sim::slamot::SlamotScenarioConfig;
use quarry::trackers::slamot::SlamotConfig;

fn main() {
    let scenario = SlamotScenarioConfig::s1();
    let config = SlamotConfig::s1();
    for seed in 0..3 {
        let ekf = run_simulated_ekf(&config, &scenario, seed).expect("ekf run");
        let pf = run_simulated(&config, &scenario, seed, filter_seed(seed, 50)).expect("rbpf run");
        for (name, r) in [("EKF ", &ekf), ("RBPF", &pf)] {
            let targets: Vec<String> = r
                .target_err
                .iter()
                .map(|e| format!("{:.3}", mean_var(e).0))
                .collect();
            println!(
                "seed {seed} {name}: robot {:.3} m, targets {} m, lost: {}",
                mean_var(&r.robot_err).0,
                targets.join(" / "),
                r.swap_or_loss
            );
        }
    }
}
