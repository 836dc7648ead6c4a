//! The lidar people tracker on recorded scans: one scanner's CSV (`stamp_s,r0..r{N-1}`) with
//! its geometry from a `scan_meta.json`, scored against labelled leg centroids. A scanner at
//! leg height: the leg detector feeding the `jipda` tracker (what `quarry lidar --scans F.csv
//! --detector legs` runs).
//!
//! Run: `cargo run --release --example lidar_recorded -- ../shared/data/leg-tracker positive_1`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::core::Pose2;
use quarry::data::leg_labels::parse_legs_csv;
use quarry::data::scans_csv::{ScanCsvOptions, parse_scan_meta, read_scans};
use quarry::repro::lidar::score_labelled;
use quarry::trackers::lidar_people::{Detector, LidarPeopleConfig, run_recorded};
use std::path::PathBuf;

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "../shared/data/leg-tracker".into()),
    );
    let key = args.next().unwrap_or_else(|| "positive_1".into());
    let meta = std::fs::read_to_string(dir.join("scan_meta.json")).expect("scan_meta.json");
    let geometry = parse_scan_meta(&meta, &key).expect("geometry");
    let (scans, stats) = read_scans(
        dir.join(format!("{key}_scans.csv")),
        geometry,
        ScanCsvOptions::default(),
    )
    .expect("scans");
    let cfg = LidarPeopleConfig {
        detector: Detector::Legs,
        ..LidarPeopleConfig::jipda()
    };
    // the scanner is the world origin; 3 periods without a scan count as a gap
    let run = run_recorded(&cfg, &geometry, Pose2::default(), &scans, 3.0).expect("run");
    println!(
        "{} scans ({} invalid beams), {} distinct tracks",
        run.frames.len(),
        stats.invalid_beams,
        run.distinct_tracks()
    );
    if let Ok(text) = std::fs::read_to_string(dir.join(format!("{key}_legs.csv"))) {
        let labels = parse_legs_csv(&text).expect("legs");
        let e = score_labelled(&run, &labels, cfg.d_match).expect("score");
        println!(
            "person position: {}/{} labelled scans matched, RMSE {:.3} m",
            e.matched, e.labelled, e.rmse_m
        );
    }
}
