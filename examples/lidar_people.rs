//! Paper 003 in a few lines: three simulated laser scanners in a room, people walking fast
//! (1.3-1.5 m/s), chi-square background subtraction on each scanner, fusion, MeanShift + ICP contour
//! detection, then the paper's Table-1 tracker (the `faithful` preset) and the `jipda` preset
//! (CV Kalman + JIPDA with track existence) on the same run.
//!
//! Run: `cargo run --release --example lidar_people`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::core::TimeUs;
use quarry::repro::lidar::{evaluate_paper003, run_room_default};
use quarry::sim::lidar_room::{Scenario, SpeedBand};
use quarry::trackers::TrackerConfig;
use quarry::trackers::lidar_people::{LidarPeopleConfig, Preset, gate_of};

fn main() {
    for preset in [Preset::Faithful, Preset::Jipda] {
        let cfg = LidarPeopleConfig::preset(preset);
        let frames = 600;
        // 7 s of warm-up for the background models, then `frames` tracked frames.
        let duration = 7.0 + frames as f64 * cfg.frame_period_s + 0.3;
        let scenario = Scenario::band(SpeedBand::Fast, 3, 1).with_duration(duration);
        let run = run_room_default(scenario, &cfg, &mut |_| {}).expect("run");
        let window = run.eval_window(TimeUs(7_000_000), frames);
        let m = evaluate_paper003(&window, &gate_of(&cfg), cfg.min_num_point, cfg.d_match)
            .expect("metrics");
        println!(
            "{preset:?}, {} frames: success {:.1} %, mean localisation error {:.3} m, MOTA {:.3}, IDF1 {:.3}",
            window.len(),
            100.0 * m.success_rate(),
            m.loc.mean,
            m.mota,
            m.idf1
        );
    }
}
