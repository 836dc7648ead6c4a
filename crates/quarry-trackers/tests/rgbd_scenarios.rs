//! Scenario tests of the RGB-D person tracker (spec 001 §6.2) on the synthetic generator.
//!
//! The default test runs one seed of S2 (fast); the full protocol (six scenarios, seeds 0-4,
//! patch tracker vs baseline) is `#[ignore]`d: run it in release with
//! `cargo test --release -p quarry-trackers --test rgbd_scenarios -- --ignored --nocapture`.

use quarry_sim::rgbd::{RgbdScene, ScenarioId};
use quarry_trackers::rgbd_person::{OdometryFeed, RgbdPersonConfig, ScenarioSummary, run_scenario};

fn run(id: ScenarioId, seed: u64, cfg: &RgbdPersonConfig, odo: OdometryFeed) -> ScenarioSummary {
    let scene = RgbdScene::new(id, seed).unwrap();
    let (s, _) = run_scenario(&scene, seed, cfg, odo, |_, _| {}).unwrap();
    println!("{}", serde_json::to_string(&s).unwrap());
    s
}

#[test]
fn s2_scale_one_seed() {
    let s = run(ScenarioId::S2Scale, 0, &RgbdPersonConfig::paper(), OdometryFeed::Exact);
    assert!(s.success_rate_iou50 >= 0.85, "{s:?}");
    assert!(s.center_err_px <= 10.0, "{s:?}");
}
