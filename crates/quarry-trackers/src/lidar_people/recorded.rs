//! The tracker on recorded scans of one scanner (`quarry lidar --scans FILE.csv`), and the
//! position error against labelled leg centroids (the leg-tracker recordings of
//! `shared/data/leg-tracker`).
//!
//! Each recorded scan goes through the client's background model and becomes one fused frame
//! of its own (one scanner: nothing to fuse; the frame time is the scan stamp, so Δt is the
//! scanner's period, not 50 ms). What is skipped, and counted in [`RecordedRun`]:
//! - a scan whose stamp is earlier than the previous accepted one (`skipped_backwards`; the
//!   background model would reject it);
//! - a scan with the wrong beam count (`skipped_bad_scans`);
//! - warm-up: the first `window_m / 2` scans are classified (they fill the background window)
//!   but not tracked — until then every beam is dynamic by rule (3) (`warm_up_scans`; their
//!   frames carry no tracks);
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
    /// Tracks reported for this scan.
    pub tracks: Vec<LidarTrack>,
}

/// The result of [`run_recorded`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RecordedRun {
    /// One entry per processed scan.
    pub frames: Vec<RecordedFrame>,
    /// Scans skipped because their stamp went backwards.
    pub skipped_backwards: usize,
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
            let dt = (scan.t.0 - t.0) as f64;
            run.longest_gap_s = run.longest_gap_s.max(dt * 1e-6);
            if dt > gap_us {
                run.gaps += 1;
            }
        }
        let t0 = Instant::now();
        let labels = bg.classify(scan)?;
        run.client_seconds += t0.elapsed().as_secs_f64();
        last_t = Some(scan.t);
        if run.warm_up_scans < cfg.window_m / 2 {
            run.warm_up_scans += 1;
            run.frames.push(RecordedFrame {
                t: scan.t,
                dynamic: labels.iter().filter(|l| **l == BeamLabel::Dynamic).count(),
                tracks: Vec::new(),
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
        });
    }
    Ok(run)
}

/// A labelled person position: the mean of the leg centroids of one scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelledPerson {
    /// Scan stamp.
    pub t: TimeUs,
    /// Position (laser frame), metres.
    pub pos: Point2,
    /// Number of leg centroids averaged.
    pub legs: usize,
}

/// Parses a `positive_k_legs.csv` (header `stamp_s,leg_index,x_m,y_m,frame_id`, one row per
/// leg) into one [`LabelledPerson`] per stamp (mean of its legs), in stamp order.
///
/// Errors name the line: a missing or different header, a wrong column count, an unparseable
/// or non-finite number.
pub fn parse_legs_csv(text: &str) -> Result<Vec<LabelledPerson>, TrackerError> {
    let bad = |line: usize, why: &str| {
        TrackerError::config("lidar_people", format!("legs csv line {line}: {why}"))
    };
    let mut lines = text.lines().enumerate();
    let header = lines
        .next()
        .map(|(_, h)| h.trim().to_string())
        .unwrap_or_default();
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    if cols.len() < 4 || cols[..4] != ["stamp_s", "leg_index", "x_m", "y_m"] {
        return Err(bad(1, "header must start with stamp_s,leg_index,x_m,y_m"));
    }
    let mut acc: std::collections::BTreeMap<i64, (f64, f64, usize)> =
        std::collections::BTreeMap::new();
    for (i, line) in lines {
        let line_no = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != cols.len() {
            return Err(bad(
                line_no,
                &format!("{} columns, the header has {}", f.len(), cols.len()),
            ));
        }
        let num = |j: usize| -> Result<f64, TrackerError> {
            let v: f64 = f[j]
                .parse()
                .map_err(|_| bad(line_no, &format!("column {} is not a number", cols[j])))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad(line_no, &format!("column {} is not finite", cols[j])))
            }
        };
        let stamp = num(0)?;
        let (x, y) = (num(2)?, num(3)?);
        let e = acc
            .entry((stamp * 1e6).round() as i64)
            .or_insert((0.0, 0.0, 0));
        e.0 += x;
        e.1 += y;
        e.2 += 1;
    }
    Ok(acc
        .into_iter()
        .map(|(t, (x, y, n))| LabelledPerson {
            t: TimeUs(t),
            pos: Point2::new(x / n as f64, y / n as f64),
            legs: n,
        })
        .collect())
}

/// Position error of a recorded run against labelled people.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct LabelledError {
    /// Labelled scans found in the run.
    pub labelled: usize,
    /// Labelled scans with a track within the match radius.
    pub matched: usize,
    /// RMSE of the matched scans, metres.
    pub rmse_m: f64,
    /// Mean error of the matched scans, metres.
    pub mean_m: f64,
    /// Median error of the matched scans, metres.
    pub median_m: f64,
    /// Matched scans whose label averaged two (or more) legs.
    pub matched_two_legs: usize,
    /// RMSE over those, metres.
    pub rmse_two_legs_m: f64,
}

/// Scores `run` against `labels`: for each labelled stamp present in the run, the nearest track
/// within `match_radius` (metres, finite and > 0) is the match. Labels whose stamp is not in
/// the run are ignored.
pub fn score_labelled(
    run: &RecordedRun,
    labels: &[LabelledPerson],
    match_radius: f64,
) -> Result<LabelledError, TrackerError> {
    if !(match_radius.is_finite() && match_radius > 0.0) {
        return Err(CoreError::invalid("match_radius", "must be finite and > 0").into());
    }
    let mut out = LabelledError::default();
    let mut errs = Vec::new();
    let mut errs2 = Vec::new();
    for l in labels {
        let Ok(i) = run.frames.binary_search_by_key(&l.t, |f| f.t) else {
            continue;
        };
        out.labelled += 1;
        let best = run.frames[i]
            .tracks
            .iter()
            .map(|t| (t.x - l.pos.x).hypot(t.y - l.pos.y))
            .fold(f64::INFINITY, f64::min);
        if best <= match_radius {
            errs.push(best);
            if l.legs >= 2 {
                errs2.push(best);
            }
        }
    }
    let rms = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt()
        }
    };
    out.matched = errs.len();
    out.matched_two_legs = errs2.len();
    out.rmse_m = rms(&errs);
    out.rmse_two_legs_m = rms(&errs2);
    out.mean_m = if errs.is_empty() {
        f64::NAN
    } else {
        errs.iter().sum::<f64>() / errs.len() as f64
    };
    errs.sort_by(f64::total_cmp);
    out.median_m = errs.get(errs.len() / 2).copied().unwrap_or(f64::NAN);
    Ok(out)
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
    fn legs_csv_parses_and_rejects() {
        let l = parse_legs_csv(
            "stamp_s,leg_index,x_m,y_m,frame_id\n1.0,0,1.0,0.0,laser\n1.0,1,1.0,0.2,laser\n2.0,0,3,3,laser\n",
        )
        .unwrap();
        assert_eq!(l.len(), 2);
        assert_eq!(l[0].legs, 2);
        assert!((l[0].pos.y - 0.1).abs() < 1e-12);
        assert!(parse_legs_csv("x,y\n").is_err());
        assert!(parse_legs_csv("stamp_s,leg_index,x_m,y_m,frame_id\n1,0,nan,0,l\n").is_err());
        assert!(parse_legs_csv("stamp_s,leg_index,x_m,y_m,frame_id\n1,0,1\n").is_err());
        assert!(parse_legs_csv("").is_err());
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
}
