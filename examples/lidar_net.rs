//! The networked lidar tracker in one process: three scanner nodes and the fusion server as
//! threads over the in-process transport, in virtual time, checked against the in-process run.
//! Swap `LocalBus` for `quarry::net::ZenohTransport` (feature `zenoh`) to put them on a
//! network; `quarry lidar-node` / `quarry lidar-server` do exactly that.
//!
//! ```sh
//! cargo run --release --example lidar_net
//! ```

use quarry::core::TimeUs;
use quarry::net::{LocalBus, run_sim_node, run_sim_server};
use quarry::repro::lidar::run_room_default;
use quarry::sim::lidar_room::{Scenario, SpeedBand};
use quarry::trackers::lidar_people::LidarPeopleConfig;
use std::time::Duration;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sc = Scenario::band(SpeedBand::Mid, 3, 1).with_duration(15.0);
    let cfg = LidarPeopleConfig::faithful();
    let sensors: Vec<_> = sc
        .scanners
        .iter()
        .map(|s| (s.id, s.pose, s.geometry))
        .collect();
    let bus = LocalBus::new();
    let nodes: Vec<_> = (0..sc.scanners.len())
        .map(|k| {
            let (bus, sc, cfg) = (bus.clone(), sc.clone(), cfg.clone());
            std::thread::spawn(move || run_sim_node(&bus, sc, k, &cfg, Duration::from_secs(10)))
        })
        .collect();
    let t_end = TimeUs((sc.duration_s * 1e6).round() as i64);
    let run = run_sim_server(&bus, &sensors, &cfg, t_end, Duration::from_secs(10))?;
    for n in nodes {
        let s = n.join().map_err(|_| "node thread panicked")??;
        println!(
            "node {}: {} scans, {} lost and {} duplicated by the simulated wifi",
            s.sensor, s.scans, s.lost, s.duplicated
        );
    }
    let st = run.stats;
    println!(
        "server: {} frames, accepted {} parts, dropped {} duplicates and {} late, {} seqs lost",
        run.frames_tracked, st.accepted, st.dup, st.late, st.lost
    );
    if let Some((k, t, rows)) = run.tracks.last() {
        println!(
            "frame {k} (t = {:.2} s): {} tracks",
            t.as_secs_f64(),
            rows.len()
        );
        for r in rows {
            println!("  track {}: ({:.2}, {:.2}) m", r.id, r.x, r.y);
        }
    }
    let local = run_room_default(sc, &cfg, &mut |_| {})?;
    println!(
        "identical to the in-process run: {}",
        local.tracks == run.tracks
    );
    Ok(())
}
