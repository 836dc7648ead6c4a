//! The tracker on the real leg-tracker recordings (`shared/data/leg-tracker`, single scanner at
//! leg height; BSD-3, Angus Leigh 2018). Skips with a printed reason when the data are absent.
//! Measured: 166/197 labelled scans matched, RMSE 0.123 m. The thresholds are these values with
//! a margin: they fail if the
//! background model, the detector or the scoring regress.

use quarry_core::Pose2;
use quarry_data::leg_labels::{LabelledScan, parse_leg_scans_csv, parse_legs_csv};
use quarry_data::scans_csv::{ScanCsvOptions, parse_scan_meta, read_scans};
use quarry_repro::lidar::{score_label_groups, score_labelled};
use quarry_trackers::lidar_people::{LidarPeopleConfig, run_recorded};
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

/// `cfg` on the three positive recordings and the demo: per recording (name, min matched
/// fraction after the warm-up, max RMSE m, max tracks living >= 1 s, min fraction of the
/// label groups — people — matched after the warm-up), and the min fraction of demo scans
/// after the warm-up with 1-4 tracks. With `backfill` the positive runs are backfilled
/// offline (`RecordedRun::backfill`, `quarry lidar --backfill`) before scoring.
fn legs_on_the_real_recordings(
    cfg: &LidarPeopleConfig,
    backfill: bool,
    limits: [(&str, f64, f64, usize, f64); 3],
    min_demo: f64,
) {
    let Some(d) = data() else { return };
    let meta = std::fs::read_to_string(d.join("scan_meta.json")).unwrap();
    for (name, min_frac, max_rmse, max_long, min_people) in limits {
        let g = parse_scan_meta(&meta, name).unwrap();
        let (scans, _) = read_scans(
            d.join(format!("{name}_scans.csv")),
            g,
            ScanCsvOptions::default(),
        )
        .unwrap();
        let mut run = run_recorded(cfg, &g, Pose2::default(), &scans, 3.0).unwrap();
        if backfill {
            run.backfill();
        }
        let label_scans = parse_leg_scans_csv(
            &std::fs::read_to_string(d.join(format!("{name}_legs.csv"))).unwrap(),
        )
        .unwrap();
        let tracked_from = run.frames[run.warm_up_scans].t;
        let after: Vec<LabelledScan> = label_scans
            .into_iter()
            .filter(|l| l.t >= tracked_from)
            .collect();
        let people: Vec<_> = after.iter().map(LabelledScan::person).collect();
        let e = score_labelled(&run, &people, cfg.d_match).unwrap();
        let pg = score_label_groups(&run, &after, cfg.d_match, cfg.leg_pair_dist).unwrap();
        eprintln!("{name}: per person {pg:?}");
        assert!(
            pg.matched as f64 >= min_people * pg.groups as f64,
            "{name}: people matched {}/{}",
            pg.matched,
            pg.groups
        );
        let long = run
            .track_lifetimes()
            .iter()
            .filter(|(_, l)| *l as f64 * g.scan_period >= 1.0)
            .count();
        eprintln!("{name}: {e:?}, {long} tracks >= 1 s");
        let frac = e.matched as f64 / e.labelled as f64;
        assert!(
            frac >= min_frac,
            "{name}: matched {}/{}",
            e.matched,
            e.labelled
        );
        assert!(e.rmse_m <= max_rmse, "{name}: RMSE {}", e.rmse_m);
        assert!(long <= max_long, "{name}: {long} tracks living >= 1 s");
    }
    let g = parse_scan_meta(&meta, "demo_stationary_simple_environment").unwrap();
    let (scans, _) = read_scans(
        d.join("demo_stationary_simple_environment_scans.csv"),
        g,
        ScanCsvOptions::default(),
    )
    .unwrap();
    let run = run_recorded(cfg, &g, Pose2::default(), &scans, 3.0).unwrap();
    let tracked = &run.frames[run.warm_up_scans..];
    let in_range = tracked
        .iter()
        .filter(|f| (1..=4).contains(&f.tracks.len()))
        .count();
    let frac = in_range as f64 / tracked.len() as f64;
    eprintln!("demo: {in_range}/{} scans with 1-4 tracks", tracked.len());
    assert!(
        frac >= min_demo,
        "demo: {in_range}/{} scans with 1-4 tracks",
        tracked.len()
    );
}

/// `kf-gnn` with `detector = legs` on the three positive recordings and the demo. Measured
/// (docs/lidar-people.md "Background relearn", stop 32): labelled scans after the warm-up
/// matched 162/179, 57/63, 117/175; RMSE 0.068 / 0.071 / 0.123 m; tracks living >= 1 s
/// 4 / 3 / 7; demo scans after the warm-up with 1-4 tracks 1155/1245 (92.8 %); people (label
/// groups, stop 37) matched after the warm-up 181/189, 57/63, 235/238. (Before the
/// relearn fix: 115/175, 0.171 m, 5 / 3 / 11, 89.6 %.) The thresholds are these values with
/// a margin; nothing was tuned on them (the parameters are leg_tracker's published defaults or
/// the physical choices in config.rs).
#[test]
fn leg_detector_on_the_real_recordings() {
    let cfg = LidarPeopleConfig {
        detector: quarry_trackers::lidar_people::Detector::Legs,
        ..LidarPeopleConfig::kf_gnn()
    };
    legs_on_the_real_recordings(
        &cfg,
        false,
        [
            ("positive_1", 0.88, 0.08, 6, 0.92),
            ("positive_2", 0.88, 0.08, 4, 0.86),
            ("positive_3", 0.64, 0.15, 9, 0.95),
        ],
        0.90,
    );
}

/// `jipda` with `detector = legs`. Measured (docs/lidar-people.md "Early start", stop 33;
/// the preset's background starts early, so every labelled scan counts: there is no warm-up):
/// matched 165/197, 70/83, 119/175; RMSE 0.063 / 0.065 / 0.145 m; tracks living >= 1 s
/// 3 / 3 / 6 (stop 34, `bg_sparse_beams`; 7 / 3 / 7 without it); demo scans with 1-4 tracks
/// 1155/1265 (91.3 %; 89.7 % without); people (label groups, stop 37) matched 184/207, 70/83,
/// 232/238. (Stop 32, scans after a 20-scan warm-up and the merge
/// rule on legs: 162/179, 57/63, 119/175; 6 / 3 / 10 long tracks.) The jipda values come from
/// the simulated room's tuning seeds, except `jipda_max_coast_report`, `leg_merge_distance`
/// and `bg_sparse_beams`, chosen after these recordings (the doc says so). Thresholds: these
/// values with a margin; positive_1's long tracks fail without `bg_sparse_beams`.
#[test]
fn jipda_with_legs_on_the_real_recordings() {
    let cfg = LidarPeopleConfig {
        detector: quarry_trackers::lidar_people::Detector::Legs,
        ..LidarPeopleConfig::jipda()
    };
    legs_on_the_real_recordings(
        &cfg,
        false,
        [
            ("positive_1", 0.82, 0.075, 4, 0.86),
            ("positive_2", 0.82, 0.08, 4, 0.80),
            ("positive_3", 0.64, 0.16, 8, 0.94),
        ],
        0.89,
    );
}

/// `jipda` / legs backfilled offline (`quarry lidar --backfill`, stop 37): a track is also
/// reported at the scans where it was detected but held back before its first report.
/// Measured: matched 184/197, 75/83, 119/175; RMSE 0.060 / 0.063 / 0.145 m; tracks living
/// at least 1 s 4 / 5 / 10 (short reported tracks grow past 1 s with their held-back scans);
/// people (label groups) matched 203/207, 75/83, 232/238. Thresholds: these values with a
/// margin; positive_1's people fail without the backfill (184/207).
#[test]
fn jipda_with_legs_backfilled_on_the_real_recordings() {
    let cfg = LidarPeopleConfig {
        detector: quarry_trackers::lidar_people::Detector::Legs,
        ..LidarPeopleConfig::jipda()
    };
    legs_on_the_real_recordings(
        &cfg,
        true,
        [
            ("positive_1", 0.90, 0.07, 5, 0.95),
            ("positive_2", 0.86, 0.075, 6, 0.86),
            ("positive_3", 0.64, 0.16, 12, 0.94),
        ],
        0.89,
    );
}

/// The recordings' own definition of the person (the mean of every leg label of a scan) caps
/// what any tracker can score: a scan whose labels hold two people far apart has its "person"
/// between them. Scored for a tracker reporting every label group exactly (docs/lidar-people.md,
/// "What the labels allow"): positive_1 188/197 (10 scans with two groups), positive_2 83/83,
/// positive_3 121/175 (63 scans with two groups, RMSE 0.116 m) — under the 95 % and
/// 0.08 m there, whatever the tracker. Pure data and scoring: no tracker runs.
#[test]
fn the_recordings_labels_cap_any_tracker_of_people() {
    let Some(d) = data() else { return };
    for (name, ceiling, labelled, multi) in [
        ("positive_1", 188, 197, 10),
        ("positive_2", 83, 83, 0),
        ("positive_3", 121, 175, 63),
    ] {
        let scans = parse_leg_scans_csv(
            &std::fs::read_to_string(d.join(format!("{name}_legs.csv"))).unwrap(),
        )
        .unwrap();
        let run = quarry_trackers::lidar_people::RecordedRun {
            frames: scans
                .iter()
                .map(|l| quarry_trackers::lidar_people::RecordedFrame {
                    t: l.t,
                    dynamic: 0,
                    tracks: Vec::new(),
                    withheld: Vec::new(),
                })
                .collect(),
            ..Default::default()
        };
        let g = score_label_groups(&run, &scans, 0.5, 0.8).unwrap();
        eprintln!("{name}: {g:?}");
        assert_eq!(
            (g.ceiling_matched, g.labelled, g.multi_group_scans),
            (ceiling, labelled, multi),
            "{name}"
        );
        assert_eq!(g.matched, 0, "{name}: no tracks, nothing matched");
    }
}
