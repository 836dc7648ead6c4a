//! The tracker on the real leg-tracker recordings (`shared/data/leg-tracker`, single scanner at
//! leg height; BSD-3, Angus Leigh 2018). Skips with a printed reason when the data are absent.
//! Measured: 166/197 labelled scans matched, RMSE 0.123 m. The thresholds are these values with
//! a margin: they fail if the
//! background model, the detector or the scoring regress.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry_core::Pose2;
use quarry_data::scans_csv::{ScanCsvOptions, parse_scan_meta, read_scans};
use quarry_trackers::lidar_people::{
    LidarPeopleConfig, parse_legs_csv, run_recorded, score_labelled,
};
use std::path::PathBuf;

fn data() -> Option<PathBuf> {
    let d = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/leg-tracker"
    ));
    if d.join("scan_meta.json").exists() {
        Some(d)
    } else {
        eprintln!("skipping: no leg-tracker data at {}", d.display());
        None
    }
}

#[test]
fn positive_1_person_position_error() {
    let Some(d) = data() else { return };
    let meta = std::fs::read_to_string(d.join("scan_meta.json")).unwrap();
    let g = parse_scan_meta(&meta, "positive_1").unwrap();
    let (scans, stats) =
        read_scans(d.join("positive_1_scans.csv"), g, ScanCsvOptions::default()).unwrap();
    assert_eq!(scans.len(), 400);
    assert_eq!(stats.skipped_bad_rows + stats.skipped_backwards, 0);
    let cfg = LidarPeopleConfig::default();
    let run = run_recorded(&cfg, &g, Pose2::default(), &scans, 3.0).unwrap();
    assert_eq!(run.frames.len(), 400);
    assert_eq!(run.gaps, 0);
    let labels =
        parse_legs_csv(&std::fs::read_to_string(d.join("positive_1_legs.csv")).unwrap()).unwrap();
    let e = score_labelled(&run, &labels, cfg.d_match).unwrap();
    eprintln!("{e:?}");
    assert!(e.labelled > 150, "labelled scans {}", e.labelled);
    assert!(
        e.matched as f64 >= 0.8 * e.labelled as f64,
        "matched {}/{}",
        e.matched,
        e.labelled
    );
    assert!(e.rmse_m < 0.16, "RMSE {}", e.rmse_m);
}
