//! One RGB-D tracker step (640×480, K = 54, the frame of the `rgbd/step_640x480_k54` bench)
//! repeated `N` times on clones of the same tracker: a load-independent profile with
//! `valgrind --tool=callgrind target/release/examples/rgbd_step 10`.
//!
//! `cargo run --release --example rgbd_step -- [N]`

use quarry::core::{EgoMotion, SingleTargetTracker, Stamp};
use quarry::sim::rgbd::{RgbdScene, ScenarioId};
use quarry::trackers::rgbd_person::{RgbdPersonConfig, RgbdPersonTracker};
use quarry::vision::multicue::RgbdFrame;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: u32 = std::env::args().nth(1).map_or(Ok(20), |s| s.parse())?;
    let scene = RgbdScene::new(ScenarioId::S1StaticOcclusion, 0)?;
    let frame = |k: usize| -> Result<(RgbdFrame, _), Box<dyn std::error::Error>> {
        let s = scene.render(k)?;
        let t = s.truth.amodal;
        Ok((
            RgbdFrame::new(640, 480, s.rgb, s.depth_m, EgoMotion::None)?,
            t,
        ))
    };
    let (f0, b0) = frame(90)?;
    let (f1, _) = frame(91)?;
    let (f2, _) = frame(92)?;
    let mut tr = RgbdPersonTracker::new(RgbdPersonConfig::paper())?;
    tr.init(Stamp::from_frame(90, scene.dt), &f0, b0.ok_or("no target")?)?;
    tr.step(Stamp::from_frame(91, scene.dt), &f1)?;
    let t0 = std::time::Instant::now();
    let mut last = None;
    for _ in 0..n {
        last = Some(tr.clone().step(Stamp::from_frame(92, scene.dt), &f2)?);
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3 / f64::from(n.max(1));
    if let Some(o) = last {
        println!(
            "{ms:.3} ms/step (wall clock), K = {}, box {:?}, state {:?}",
            o.n_candidates, o.bbox, o.state
        );
    }
    Ok(())
}
