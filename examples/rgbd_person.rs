//! RGB-D person tracking (spec 001) on a synthetic scenario: the patch multi-cue tracker against
//! the whole-target baseline.
//!
//! `cargo run --release --example rgbd_person -- [s1..s6] [seed]`

use quarry::repro::rgbd::{OdometryFeed, run_scenario};
use quarry::sim::rgbd::{RgbdScene, ScenarioId};
use quarry::trackers::rgbd_person::RgbdPersonConfig;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let id = ScenarioId::from_name(&args.next().unwrap_or_else(|| "s1".into()))?;
    let seed: u64 = args.next().map_or(Ok(0), |s| s.parse())?;
    let scene = RgbdScene::new(id, seed)?;
    for (name, cfg) in [
        ("patch", RgbdPersonConfig::paper()),
        ("baseline", RgbdPersonConfig::whole_target_baseline()),
    ] {
        let (s, frames) = run_scenario(&scene, seed, &cfg, OdometryFeed::Exact, |_, _| {})?;
        let last = frames
            .last()
            .map(|f| format!("{:?}", f.state))
            .unwrap_or_default();
        println!(
            "{} {name:8} success@0.5 {:.3}  CLE {:.1} px  recovery {:?}  updates(vis<0.6) {}  last state {last}",
            id.name(),
            s.success_rate_iou50,
            s.center_err_px,
            s.recovery_frames,
            s.updates_low_visibility
        );
    }
    Ok(())
}
