//! The lidar people tracker on recorded scans: one scanner's CSV (`stamp_s,r0..r{N-1}`) with
//! its geometry from a `scan_meta.json`, scored against labelled leg centroids. A scanner at
//! leg height: the leg detector feeding the `jipda` tracker (what `quarry lidar --scans F.csv
//! --detector legs` runs).
//!
//! Run: `cargo run --release --example lidar_recorded -- ../shared/data/leg-tracker positive_1`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::core::Pose2;
use quarry::data::leg_labels::{LabelledScan, parse_leg_scans_csv};
use quarry::data::scans_csv::{ScanCsvOptions, parse_scan_meta, read_scans};
use quarry::repro::lidar::{score_label_groups, score_labelled};
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
        let scans = parse_leg_scans_csv(&text).expect("legs");
        // the recordings' person: the mean of every leg labelled in the scan
        let people: Vec<_> = scans.iter().map(LabelledScan::person).collect();
        let e = score_labelled(&run, &people, cfg.d_match).expect("score");
        println!(
            "person position: {}/{} labelled scans matched, RMSE {:.3} m",
            e.matched, e.labelled, e.rmse_m
        );
        // the labels split into people (legs within 0.8 m of each other), each scored alone
        let g = score_label_groups(&run, &scans, cfg.d_match, cfg.leg_pair_dist).expect("score");
        println!(
            "per person: {}/{} matched, RMSE {:.3} m ({} scans label two people or more)",
            g.matched, g.groups, g.rmse_m, g.multi_group_scans
        );
    }
}
