//! The tracker on recorded scans of one scanner (`quarry lidar --scans FILE.csv`; the scans
//! come from quarry-data's `scans_csv` reader or from the user's own driver). The scoring
//! against labelled leg centroids is quarry-repro's.
//!
//! Each recorded scan goes through the client's background model and becomes one fused frame
//! of its own (one scanner: nothing to fuse; the frame time is the scan stamp, so Δt is the
//! scanner's period, not 50 ms). What is skipped, and counted in [`RecordedRun`]:
//! - a scan whose stamp is earlier than the previous accepted one (`skipped_backwards`; the
//!   background model would reject it), or equal to it (`skipped_repeated`: a duplicated scan;
//!   time standing still would make every track's Δt zero);
//! - a scan with the wrong beam count (`skipped_bad_scans`);
//! - warm-up: the first `window_m / 2` scans are classified (they fill the background window)
//!   but not tracked — until then every beam is dynamic by rule (3) (`warm_up_scans`; their
//!   frames carry no tracks). With `bg_early_start_m > 0` (the `jipda` preset) nothing is
//!   skipped: the background's early start labels those scans, and tracking starts at the
//!   first one (`warm_up_scans` = 0);
//! - a gap: the scanner stopped sending for more than `gap_factor` periods (`gaps`, the longest
//!   in `longest_gap_s`). Nothing is invented for the missing time; the tracker sees a longer Δt
//!   on the next scan, and Table 1 gate (8) then decides whether tracks survive.

use super::config::LidarPeopleConfig;
use super::tracker::{FusedPoints, LidarTrack};
use super::{DefaultLidarTracker, background_of};
use crate::TrackerError;
use quarry_cloud::scan::BeamTable;
use quarry_core::{
    BackgroundModel, BeamLabel, CoreError, FrameIndex, MultiTargetTracker, Point2, PolarScan,
    Pose2, ScanGeometry, Stamp, TimeUs,
};
use std::time::Instant;

/// One processed scan.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedFrame {
    /// Scan stamp.
    pub t: TimeUs,
    /// Beams labelled dynamic.
    pub dynamic: usize,
    /// Tracks reported for this scan, in id order.
    pub tracks: Vec<LidarTrack>,
    /// Tracks detected in this scan but held back (not confirmed yet, or not yet walked
    /// `leg_min_travel_m`), in id order: what [`RecordedRun::backfill`] may report.
    pub withheld: Vec<LidarTrack>,
}

/// The result of [`run_recorded`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RecordedRun {
    /// One entry per processed scan.
    pub frames: Vec<RecordedFrame>,
    /// Scans skipped because their stamp went backwards.
    pub skipped_backwards: usize,
    /// Scans skipped because their stamp repeated the previous accepted one's.
    pub skipped_repeated: usize,
    /// Scans skipped because their beam count or geometry differs from the run's.
    pub skipped_bad_scans: usize,
    /// Scans classified but not tracked while the background window filled.
    pub warm_up_scans: usize,
    /// Gaps longer than `gap_factor` scan periods.
    pub gaps: usize,
    /// Longest interval between consecutive processed scans, seconds.
    pub longest_gap_s: f64,
    /// Background-model time, seconds.
    pub client_seconds: f64,
    /// Tracker time, seconds.
    pub tracker_seconds: f64,
}

impl RecordedRun {
    /// Distinct track ids over the run.
    pub fn distinct_tracks(&self) -> usize {
        let mut ids: Vec<u32> = self
            .frames
            .iter()
            .flat_map(|f| f.tracks.iter().map(|t| t.id))
            .collect();
        ids.sort_unstable();
        ids.dedup();
        ids.len()
    }

    /// Histogram of the number of tracks per scan (index = track count).
    pub fn track_count_histogram(&self) -> Vec<usize> {
        let mut h = Vec::new();
        for f in &self.frames {
            if h.len() <= f.tracks.len() {
                h.resize(f.tracks.len() + 1, 0);
            }
            h[f.tracks.len()] += 1;
        }
        h
    }

    /// Offline retrodiction: a track that is reported at some scan is also reported at the
    /// earlier scans where it was detected but held back (tentative, or not yet walked
    /// `leg_min_travel_m`), with the estimate it had then. A live tracker cannot know at
    /// birth that a track will turn out to be a person; a recording can, once it has seen the
    /// whole track. A person who stands still, then walks, is then reported from their first
    /// detection instead of from their first 0.5 m; clutter that never qualifies is never
    /// reported. Rows already reported are unchanged, except that `born` moves to the
    /// track's first row. Returns the number of rows added; every `withheld` list is
    /// emptied.
    ///
    /// ```
    /// use quarry_core::TimeUs;
    /// use quarry_trackers::lidar_people::{LidarTrack, RecordedFrame, RecordedRun};
    /// let row = |id: u32, born: bool| LidarTrack {
    ///     id, x: 0.0, y: 0.0, alpha: 0.0, vx: 0.0, vy: 0.0, support: 0, rms: 0.0,
    ///     born, gate_replaced: false,
    /// };
    /// let frame = |t: i64, tracks: Vec<LidarTrack>, withheld: Vec<LidarTrack>| RecordedFrame {
    ///     t: TimeUs(t), dynamic: 0, tracks, withheld,
    /// };
    /// // track 1 held back for two scans, then reported; track 2 never reported
    /// let mut run = RecordedRun {
    ///     frames: vec![
    ///         frame(0, vec![], vec![row(1, false), row(2, false)]),
    ///         frame(1, vec![], vec![row(1, false)]),
    ///         frame(2, vec![row(1, true)], vec![row(2, false)]),
    ///     ],
    ///     ..RecordedRun::default()
    /// };
    /// assert_eq!(run.backfill(), 2);
    /// assert_eq!(run.track_lifetimes(), vec![(1, 3)]);
    /// assert!(run.frames[0].tracks[0].born && !run.frames[2].tracks[0].born);
    /// ```
    pub fn backfill(&mut self) -> usize {
        let mut first: std::collections::BTreeMap<u32, usize> = std::collections::BTreeMap::new();
        for (k, f) in self.frames.iter().enumerate() {
            for t in &f.tracks {
                first.entry(t.id).or_insert(k);
            }
        }
        // an id's first row is reported at `first[id]`: a frame before it holds no row of it
        let mut backfilled = std::collections::BTreeSet::new();
        let mut added = 0;
        for (k, f) in self.frames.iter_mut().enumerate() {
            let before = f.tracks.len();
            for w in std::mem::take(&mut f.withheld) {
                if first.get(&w.id).is_some_and(|&k0| k < k0) {
                    // the earliest row of the id is its birth
                    let born = backfilled.insert(w.id);
                    f.tracks.push(LidarTrack { born, ..w });
                }
            }
            if f.tracks.len() > before {
                added += f.tracks.len() - before;
                f.tracks.sort_by_key(|t| t.id);
            }
        }
        for id in backfilled {
            for t in &mut self.frames[first[&id]].tracks {
                if t.id == id {
                    t.born = false;
                }
            }
        }
        added
    }

    /// Lifetimes of the tracks in scans (one entry per id, sorted by id).
    pub fn track_lifetimes(&self) -> Vec<(u32, usize)> {
        let mut m = std::collections::BTreeMap::new();
        for f in &self.frames {
            for t in &f.tracks {
                *m.entry(t.id).or_insert(0usize) += 1;
            }
        }
        m.into_iter().collect()
    }
}

/// Runs the tracker of `cfg` over recorded scans of one scanner placed at `pose` in the world.
///
/// `gap_factor` (> 1) sets what counts as a gap (3 is a good value). Errors: an invalid
/// configuration or geometry, or a non-finite pose or gap factor; bad scans are skipped and
/// counted (module docs).
pub fn run_recorded(
    cfg: &LidarPeopleConfig,
    geometry: &ScanGeometry,
    pose: Pose2,
    scans: &[PolarScan],
    gap_factor: f64,
) -> Result<RecordedRun, TrackerError> {
    if !(pose.x.is_finite() && pose.y.is_finite() && pose.theta.is_finite()) {
        return Err(CoreError::invalid("pose", "must be finite").into());
    }
    if !(gap_factor.is_finite() && gap_factor > 1.0) {
        return Err(CoreError::invalid("gap_factor", "must be finite and > 1").into());
    }
    let mut bg = background_of(cfg, geometry)?;
    let mut tracker = DefaultLidarTracker::from_config(cfg)?;
    let table = BeamTable::new(geometry).map_err(CoreError::from)?;
    let (s, c) = pose.theta.sin_cos();
    let gap_us = gap_factor * geometry.scan_period * 1e6;
    let mut run = RecordedRun::default();
    let mut last_t: Option<TimeUs> = None;
    for (k, scan) in scans.iter().enumerate() {
        if scan.geometry != *geometry || scan.ranges_mm.len() != geometry.n_beams as usize {
            run.skipped_bad_scans += 1;
            continue;
        }
        if let Some(t) = last_t {
            if scan.t < t {
                run.skipped_backwards += 1;
                continue;
            }
            if scan.t == t {
                run.skipped_repeated += 1;
                continue;
            }
            // scan.t > t here; the difference of two i64 stamps can exceed i64 (absurd stamps
            // from a malformed file), the absolute difference cannot exceed u64
            let dt = scan.t.0.abs_diff(t.0) as f64;
            run.longest_gap_s = run.longest_gap_s.max(dt * 1e-6);
            if dt > gap_us {
                run.gaps += 1;
            }
        }
        let t0 = Instant::now();
        let labels = bg.classify(scan)?;
        run.client_seconds += t0.elapsed().as_secs_f64();
        last_t = Some(scan.t);
        if cfg.bg_early_start_m == 0.0 && run.warm_up_scans < cfg.window_m / 2 {
            run.warm_up_scans += 1;
            run.frames.push(RecordedFrame {
                t: scan.t,
                dynamic: labels.iter().filter(|l| **l == BeamLabel::Dynamic).count(),
                tracks: Vec::new(),
                withheld: Vec::new(),
            });
            continue;
        }
        let mut points = Vec::new();
        for (n, l) in labels.iter().enumerate() {
            if *l != BeamLabel::Dynamic {
                continue;
            }
            let Some(p) = scan.range_m(n).and_then(|r| table.point(n, r)) else {
                continue;
            };
            points.push(Point2::new(
                pose.x + c * p.x - s * p.y,
                pose.y + s * p.x + c * p.y,
            ));
        }
        let frame = FusedPoints {
            t: scan.t,
            points,
            no_data: false,
        };
        let t1 = Instant::now();
        tracker.step(
            Stamp {
                frame: FrameIndex(k as u64),
                t: scan.t,
            },
            &frame,
        )?;
        run.tracker_seconds += t1.elapsed().as_secs_f64();
        run.frames.push(RecordedFrame {
            t: scan.t,
            dynamic: frame.points.len(),
            tracks: tracker.last_rows().to_vec(),
            withheld: tracker.last_withheld().to_vec(),
        });
    }
    Ok(run)
}

#[cfg(test)]
mod tests {
    use super::*;
    use quarry_core::SensorId;

    fn geom() -> ScanGeometry {
        ScanGeometry {
            n_beams: 181,
            angle_min: -std::f64::consts::FRAC_PI_2,
            angle_increment: std::f64::consts::PI / 180.0,
            range_min: 0.05,
            range_max: 10.0,
            scan_period: 0.1,
        }
    }

    #[test]
    fn backwards_gaps_and_bad_scans_are_counted() {
        let g = geom();
        let mk =
            |t: i64| PolarScan::try_new(SensorId(0), 0, TimeUs(t), vec![5000; 181], g).unwrap();
        let mut scans: Vec<PolarScan> = (0..100).map(|k| mk(k * 100_000)).collect();
        scans.insert(50, mk(1_000_000)); // backwards
        scans.push(mk(20_000_000)); // gap
        let mut other = g;
        other.n_beams = 10;
        scans.push(
            PolarScan::try_new(SensorId(0), 0, TimeUs(20_100_000), vec![5000; 10], other).unwrap(),
        );
        let cfg = LidarPeopleConfig::default();
        let run = run_recorded(&cfg, &g, Pose2::default(), &scans, 3.0).unwrap();
        assert_eq!(run.skipped_backwards, 1);
        assert_eq!(run.skipped_bad_scans, 1);
        assert_eq!(run.gaps, 1);
        assert_eq!(run.frames.len(), 101);
        assert_eq!(run.warm_up_scans, 20);
        // a static wall never makes a track
        assert_eq!(run.distinct_tracks(), 0);
        assert!(run_recorded(&cfg, &g, Pose2::default(), &scans, 0.5).is_err());
        let nan = Pose2 {
            x: f64::NAN,
            ..Pose2::default()
        };
        assert!(run_recorded(&cfg, &g, nan, &scans, 3.0).is_err());
    }

    /// Stamps at the ends of i64 (a malformed recording) are a clear error or a counted gap,
    /// never an overflow panic.
    #[test]
    fn extreme_stamps_do_not_overflow() {
        let g = geom();
        let mk =
            |t: i64| PolarScan::try_new(SensorId(0), 0, TimeUs(t), vec![5000; 181], g).unwrap();
        let mut scans: Vec<PolarScan> = (0..25).map(|k| mk(i64::MIN + 1 + k * 100_000)).collect();
        scans.push(mk(i64::MAX));
        let cfg = LidarPeopleConfig::default();
        match run_recorded(&cfg, &g, Pose2::default(), &scans, 3.0) {
            Ok(run) => {
                assert_eq!(run.gaps, 1);
                assert!(run.longest_gap_s > 1e12);
            }
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }

    /// A person walking across the scanner's view from the first scan, at leg height: the two
    /// legs are discs of radius 0.06 m, 0.2 m apart, the wall at 5 m; 1 m/s along y at x = 2 m.
    fn walker_scans() -> (ScanGeometry, Vec<PolarScan>) {
        // half-degree beams: a leg at 2 m spans three or more
        let g = ScanGeometry {
            n_beams: 361,
            angle_increment: std::f64::consts::PI / 360.0,
            ..geom()
        };
        let scans = (0..60)
            .map(|k| {
                let y = -1.5 + 0.1 * f64::from(k);
                let legs = [(2.0, y - 0.1), (2.0, y + 0.1)];
                let ranges = (0..361)
                    .map(|n| {
                        let a = g.angle_min + f64::from(n) * g.angle_increment;
                        let (s, c) = a.sin_cos();
                        let mut r = 5.0 / c.max(1e-3);
                        for (lx, ly) in legs {
                            // ray t·(c, s) against the disc: t² − 2t(c·lx + s·ly) + |l|² − ρ² = 0
                            let b = c * lx + s * ly;
                            let disc = b * b - (lx * lx + ly * ly - 0.06 * 0.06);
                            if disc >= 0.0 {
                                r = r.min(b - disc.sqrt());
                            }
                        }
                        if r < 10.0 {
                            (r * 1000.0).round() as u16
                        } else {
                            0
                        }
                    })
                    .collect();
                PolarScan::try_new(SensorId(0), k, TimeUs(i64::from(k) * 100_000), ranges, g)
                    .unwrap()
            })
            .collect();
        (g, scans)
    }

    /// With `bg_early_start_m` the background labels the first `window_m / 2` scans and the
    /// walker is tracked before the window has filled; without it nothing is tracked before
    /// scan 20. With early start every reported row is on the walker; without it the spec's
    /// model also reports the wall just uncovered behind the walker's shadow (its window still
    /// holds the legs, and b_n is learned only after `t_warm_s`): a second track along the wall.
    #[test]
    fn early_start_tracks_a_walker_before_the_window_fills() {
        let (g, scans) = walker_scans();
        let run_with = |early: f64| {
            let cfg = LidarPeopleConfig {
                detector: super::super::config::Detector::Legs,
                bg_early_start_m: early,
                ..LidarPeopleConfig::jipda()
            };
            let run = run_recorded(&cfg, &g, Pose2::default(), &scans, 3.0).unwrap();
            assert_eq!(run.warm_up_scans, if early > 0.0 { 0 } else { 20 });
            let first = run.frames.iter().position(|f| !f.tracks.is_empty());
            (run, first.expect("a track"))
        };
        let (early, first) = run_with(0.10);
        assert!(first < 12, "first track at scan {first}");
        assert_eq!(early.distinct_tracks(), 1);
        for (k, f) in early.frames.iter().enumerate() {
            let y = -1.5 + 0.1 * k as f64;
            for t in &f.tracks {
                assert!(
                    (t.x - 2.0).abs() < 0.15 && (t.y - y).abs() < 0.3,
                    "({}, {}) at scan {k}",
                    t.x,
                    t.y
                );
            }
        }
        let (spec, first) = run_with(0.0);
        assert!(first >= 20, "first track at scan {first}");
        assert!(spec.distinct_tracks() >= 1);
    }

    fn row(id: u32, x: f64, born: bool) -> LidarTrack {
        LidarTrack {
            id,
            x,
            y: 0.0,
            alpha: 0.0,
            vx: 0.0,
            vy: 0.0,
            support: 1,
            rms: 0.0,
            born,
            gate_replaced: false,
        }
    }

    proptest::proptest! {
        /// Backfill keeps every reported row (only `born` may move to an earlier row of the
        /// same id), adds only rows of ids reported somewhere, at frames before their first
        /// report, never two rows of one id in a frame, keeps each frame in id order, and
        /// empties every `withheld`.
        #[test]
        fn backfill_only_adds_held_back_rows_of_reported_ids(
            frames in proptest::collection::vec(
                (proptest::collection::btree_set(0u32..6, 0..4),
                 proptest::collection::btree_set(0u32..6, 0..4)),
                0..30),
        ) {
            let mut run = RecordedRun::default();
            let mut seen = std::collections::BTreeSet::new();
            for (k, (rep, held)) in frames.iter().enumerate() {
                run.frames.push(RecordedFrame {
                    t: TimeUs(k as i64),
                    dynamic: 0,
                    tracks: rep.iter().map(|&id| row(id, k as f64, seen.insert(id))).collect(),
                    withheld: held.iter().map(|&id| row(id, -(k as f64), false)).collect(),
                });
            }
            let before = run.clone();
            let added = run.backfill();
            let mut first = std::collections::BTreeMap::new();
            for (k, f) in before.frames.iter().enumerate() {
                for t in &f.tracks {
                    first.entry(t.id).or_insert(k);
                }
            }
            let mut n_added = 0;
            for (k, (a, b)) in run.frames.iter().zip(&before.frames).enumerate() {
                proptest::prop_assert!(a.withheld.is_empty());
                proptest::prop_assert!(a.tracks.windows(2).all(|w| w[0].id < w[1].id));
                for t in &b.tracks {
                    let now = a.tracks.iter().find(|u| u.id == t.id);
                    let kept = now.is_some_and(|u| LidarTrack { born: t.born, ..*u } == *t);
                    proptest::prop_assert!(kept, "a reported row changed");
                }
                for t in &a.tracks {
                    if b.tracks.iter().any(|u| u.id == t.id) {
                        continue;
                    }
                    n_added += 1;
                    proptest::prop_assert!(first.get(&t.id).is_some_and(|&k0| k < k0));
                    proptest::prop_assert!(b.withheld.iter().any(|w| w.id == t.id && w.x == t.x));
                }
            }
            proptest::prop_assert_eq!(n_added, added);
            // one born row per id, on its first row
            let mut born_seen = std::collections::BTreeSet::new();
            for f in &run.frames {
                for t in &f.tracks {
                    proptest::prop_assert_eq!(t.born, born_seen.insert(t.id));
                }
            }
        }
    }
}
