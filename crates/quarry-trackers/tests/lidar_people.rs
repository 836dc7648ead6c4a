//! Scenario tests of the spec 003 tracker on the room simulator (short versions; the full
//! Table 2 protocol runs through `quarry lidar` and is reported in docs/lidar-people.md).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry_core::TimeUs;
use quarry_sim::lidar_room::{Scenario, SpeedBand};
use quarry_trackers::lidar_people::{
    LidarPeopleConfig, Paper003Metrics, Preset, evaluate_paper003, gate_of, run_room_default,
};

fn run(sc: Scenario, preset: Preset, frames: usize) -> Paper003Metrics {
    let cfg = LidarPeopleConfig::preset(preset);
    let run = run_room_default(sc, &cfg, &mut |_| {}).unwrap();
    let w = run.eval_window(TimeUs(7_000_000), frames);
    assert_eq!(w.len(), frames);
    let m = evaluate_paper003(&w, &gate_of(&cfg), cfg.min_num_point, cfg.d_match).unwrap();
    eprintln!(
        "{preset:?}: success {:.3} det {:.3} loc {:.3} mota {:.3} idf1 {:.3} hota {:.3} idsw {} fp {} fn {}",
        m.success_rate(),
        m.success_rate_detectable(),
        m.loc.mean,
        m.mota,
        m.idf1,
        m.hota,
        m.idsw,
        m.fp,
        m.fn_
    );
    m
}

#[test]
fn band_mid_short_faithful_and_kf_gnn() {
    let sc = Scenario::band(SpeedBand::Mid, 3, 1).with_duration(27.0);
    let f = run(sc.clone(), Preset::Faithful, 400);
    let k = run(sc, Preset::KfGnn, 400);
    for m in [&f, &k] {
        assert!(m.loc.mean < 0.08, "localisation {}", m.loc.mean);
        assert!(m.mota > 0.7, "MOTA {}", m.mota);
    }
    assert!(
        f.success_rate() > 0.7,
        "faithful success {}",
        f.success_rate()
    );
}

#[test]
fn single_walker_is_tracked() {
    let sc = Scenario::single_line(3).with_duration(20.0);
    let m = run(sc, Preset::Faithful, 260);
    assert!(m.loc.mean < 0.06, "mean error {}", m.loc.mean);
    assert!(m.loc.p95 < 0.12, "p95 {}", m.loc.p95);
    assert!(m.success_rate() > 0.9, "success {}", m.success_rate());
}
