//! The `door` scenario of spec 003 §5: five visitors come in through the door of the simulated
//! room, walk about and leave again. Prints when each person appears and leaves (ground truth)
//! and how many track ids the `kf-gnn` preset started, with the paper's success rate.
//! (`side_by_side` and `stop_and_go` run the same way: `Scenario::by_name(name, seed)`.)
//!
//! Run: `cargo run --release --example lidar_door`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::core::TimeUs;
use quarry::repro::lidar::{evaluate_paper003, run_room_default};
use quarry::sim::lidar_room::Scenario;
use quarry::trackers::lidar_people::{LidarPeopleConfig, gate_of};
use std::collections::{BTreeMap, BTreeSet};

fn main() {
    let cfg = LidarPeopleConfig::kf_gnn();
    let scenario = Scenario::door(1); // 90 s, visitors born at 5-37 s
    let run = run_room_default(scenario, &cfg, &mut |_| {}).expect("run");
    let mut life: BTreeMap<u32, (f64, f64)> = BTreeMap::new();
    for f in &run.gt {
        let t = f.t.0 as f64 * 1e-6;
        for p in &f.people {
            life.entry(p.id).or_insert((t, t)).1 = t;
        }
    }
    for (id, (born, gone)) in &life {
        println!("person {id}: in the simulation from {born:.2} s to {gone:.2} s");
    }
    // evaluated from t = 7 s (the first 5 s are the background models' warm-up)
    let window = run.eval_window(TimeUs(7_000_000), usize::MAX);
    let ids: BTreeSet<u32> = window
        .iter()
        .flat_map(|f| f.tracks.iter().map(|t| t.0))
        .collect();
    let m = evaluate_paper003(&window, &gate_of(&cfg), cfg.min_num_point, cfg.d_match)
        .expect("metrics");
    println!(
        "{} frames from 7 s: {} track ids, success {:.1} %, MOTA {:.3}",
        window.len(),
        ids.len(),
        100.0 * m.success_rate(),
        m.mota
    );
}
