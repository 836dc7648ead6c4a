//! Fuzz the recorded-scan path of `quarry lidar --scans`: the legs CSV parser, and the scan CSV
//! reader feeding `run_recorded` (background, then the tracker the first byte picks: Table 1,
//! `kf-gnn` or `jipda`, with the contour or the leg detector; bit 3 turns on the background's
//! early start) and both scores, `score_labelled` and `score_label_groups` (the label groups of
//! `parse_leg_scans_csv`, which must average to `parse_legs_csv`'s people).
//! Any bytes: a result or a typed error, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::{Pose2, ScanGeometry};
use quarry_data::leg_labels::{LabelledScan, parse_leg_scans_csv, parse_legs_csv};
use quarry_data::scans_csv::{RowPolicy, ScanCsvOptions, ScanCsvReader};
use quarry_repro::lidar::{score_label_groups, score_labelled};
use quarry_trackers::TrackerConfig;
use quarry_trackers::lidar_people::{Detector, LidarPeopleConfig, Preset, run_recorded};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let labels = parse_legs_csv(&text).unwrap_or_default();
    let label_scans = parse_leg_scans_csv(&text).unwrap_or_default();
    let people: Vec<_> = label_scans.iter().map(LabelledScan::person).collect();
    assert_eq!(people, labels);
    let g = ScanGeometry {
        n_beams: 8,
        angle_min: -1.0,
        angle_increment: 0.25,
        range_min: 0.02,
        range_max: 12.0,
        scan_period: 0.1,
    };
    let opts = ScanCsvOptions {
        bad_rows: RowPolicy::Skip,
        backwards: RowPolicy::Skip,
        ..Default::default()
    };
    let Ok(rdr) = ScanCsvReader::new(data, g, opts) else {
        return;
    };
    let scans: Vec<_> = rdr.take(2_000).filter_map(Result::ok).collect();
    let pick = data.first().copied().unwrap_or(0);
    let (preset, detector) = match pick % 5 {
        0 => (Preset::Faithful, Detector::Contour),
        1 => (Preset::KfGnn, Detector::Contour),
        2 => (Preset::KfGnn, Detector::Legs),
        3 => (Preset::Jipda, Detector::Contour),
        _ => (Preset::Jipda, Detector::Legs),
    };
    let cfg = LidarPeopleConfig {
        t_warm_s: 0.5,
        detector,
        bg_early_start_m: if pick & 8 != 0 { 0.1 } else { 0.0 },
        bg_sparse_beams: pick & 16 != 0,
        ..LidarPeopleConfig::preset(preset)
    };
    if let Ok(run) = run_recorded(&cfg, &g, Pose2::default(), &scans, 3.0) {
        assert!(run.frames.len() <= scans.len());
        let _ = score_labelled(&run, &labels, 0.5);
        let link = [0.8, 0.1, 3.0, 0.0][usize::from(pick >> 6)];
        if let Ok(s) = score_label_groups(&run, &label_scans, 0.5, link) {
            assert!(s.matched <= s.groups && s.ceiling_matched <= s.labelled);
            assert!(s.labelled <= s.groups && s.multi_group_scans <= s.labelled);
        } else {
            assert!(link == 0.0, "only the zero link is refused");
        }
    }
});
