//! Scenario tests of the RGB-D person tracker (spec 001 §6.2) on the synthetic generator.
//!
//! The default test runs one seed of S2 (fast); the full protocol (six scenarios, seeds 0-4,
//! patch tracker vs baseline) is `#[ignore]`d: run it in release with
//! `cargo test --release -p quarry-trackers --test rgbd_scenarios -- --ignored --nocapture`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

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
    let s = run(
        ScenarioId::S2Scale,
        0,
        &RgbdPersonConfig::paper(),
        OdometryFeed::Exact,
    );
    assert!(s.success_rate_iou50 >= 0.85, "{s:?}");
    assert!(s.center_err_px <= 10.0, "{s:?}");
}

/// Mean of a field over seeds 0-4.
fn mean(v: &[ScenarioSummary], f: impl Fn(&ScenarioSummary) -> f64) -> f64 {
    v.iter().map(f).sum::<f64>() / v.len() as f64
}

fn seeds(id: ScenarioId, cfg: &RgbdPersonConfig, odo: OdometryFeed) -> Vec<ScenarioSummary> {
    (0..5).map(|s| run(id, s, cfg, odo)).collect()
}

/// S1 (static robot, crossing occluder): the patch tracker keeps and recovers the target and
/// learns nothing while it is hidden; the whole-target baseline does worse.
#[test]
#[ignore = "long protocol (5 seeds x 360 frames x 2 trackers); run in release"]
fn s1_patch_vs_baseline() {
    let p = seeds(
        ScenarioId::S1StaticOcclusion,
        &RgbdPersonConfig::paper(),
        OdometryFeed::Exact,
    );
    let b = seeds(
        ScenarioId::S1StaticOcclusion,
        &RgbdPersonConfig::whole_target_baseline(),
        OdometryFeed::Exact,
    );
    let sp = mean(&p, |s| s.success_rate_iou50);
    let sb = mean(&b, |s| s.success_rate_iou50);
    println!("S1 success patch {sp:.3} baseline {sb:.3}");
    assert!(sp >= 0.85, "patch success {sp}");
    assert!(mean(&p, |s| s.center_err_px) <= 10.0);
    for s in &p {
        assert!(s.success_rate_iou50 >= 0.80, "{s:?}");
        assert!(s.recovery_frames.is_some_and(|r| r <= 10), "{s:?}");
        assert_eq!(s.updates_low_visibility, 0, "{s:?}");
        assert!(s.occlusion_recall.unwrap_or(0.0) >= 0.8, "{s:?}");
    }
    assert!(sb <= sp - 0.10 || b.iter().any(|s| s.recovery_frames.is_none()));
}

/// S2-S5 with the patch tracker (spec §6.2 thresholds).
#[test]
#[ignore = "long protocol; run in release"]
fn s2_to_s5_patch() {
    let c = RgbdPersonConfig::paper();
    let s2 = seeds(ScenarioId::S2Scale, &c, OdometryFeed::Exact);
    assert!(mean(&s2, |s| s.success_rate_iou50) >= 0.85);
    let s3 = seeds(ScenarioId::S3Follow, &c, OdometryFeed::Exact);
    assert!(mean(&s3, |s| s.success_rate_iou50) >= 0.75);
    assert!(mean(&s3, |s| s.rmse_3d_m) <= 0.15);
    let s4 = seeds(ScenarioId::S4Illumination, &c, OdometryFeed::Exact);
    assert!(mean(&s4, |s| s.success_rate_iou50) >= 0.80);
    assert!(s4.iter().all(|s| s.lost_frames == 0));
    let s5 = seeds(ScenarioId::S5Distractor, &c, OdometryFeed::Exact);
    assert!(mean(&s5, |s| s.success_rate_iou50) >= 0.85);
    assert!(s5.iter().all(|s| s.distractor_frames == 0));
}

/// S6: the MEKF alone bridges a 31-frame detector blackout while the robot turns.
#[test]
#[ignore = "long protocol; run in release"]
fn s6_mekf_blackout() {
    let c = RgbdPersonConfig::paper();
    let exact = seeds(ScenarioId::S6EgoRotation, &c, OdometryFeed::Exact);
    let noisy = seeds(ScenarioId::S6EgoRotation, &c, OdometryFeed::Noisy);
    let no_ego = seeds(
        ScenarioId::S6EgoRotation,
        &RgbdPersonConfig { ego: false, ..c },
        OdometryFeed::Exact,
    );
    let e = mean(&exact, |s| s.blackout_end_err_px.unwrap_or(f64::INFINITY));
    let n = mean(&noisy, |s| s.blackout_end_err_px.unwrap_or(f64::INFINITY));
    let z = mean(&no_ego, |s| s.blackout_end_err_px.unwrap_or(f64::INFINITY));
    println!("S6 blackout-end error: exact {e:.1} px, noisy {n:.1} px, no_ego {z:.1} px");
    assert!(e <= 10.0 && n <= 25.0 && z >= 3.0 * e);
}
