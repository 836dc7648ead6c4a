//! [`JipdaPeopleTracker`], the tracker of the `jipda` preset: the people detector of the other
//! presets (contour fits, or leg pairs with `detector = legs`) feeding the stand-alone
//! [`JpdaTracker`](crate::cv_jpda::JpdaTracker) of `cv_jpda` in JIPDA mode.
//!
//! What it adds around that tracker: the detector, the orientation / residual / support of the
//! detection a track took (for the `tracks.csv` columns), `leg_min_travel_m` (a leg track is
//! reported only once it has walked), and stamps that never go backwards (a frame stamped
//! before the previous one is taken as simultaneous with it, as `kf-gnn` does).

use std::collections::BTreeMap;

use quarry_assoc::lifecycle::TrackState;
use quarry_cloud::legs::LegDetector;
use quarry_core::{
    Clusterer, MultiTargetTracker, Point2, Registration2, Stamp, TimeUs, TrackReport, TrackStatus,
};

use super::config::LidarPeopleConfig;
use super::tracker::{
    ContourDetector, FusedPoints, LidarTrack, detect_people, frame_points, leg_detector_of, report,
    with_heading_cov,
};
use crate::TrackerError;
use crate::cv_jpda::{JpdaTracker, JpdaTrackerConfig};

/// What the tracker keeps per track beside the JIPDA state.
#[derive(Debug, Clone, Copy)]
struct Extra {
    origin: Point2,
    moved: bool,
    reported: bool,
    /// Consecutive frames without a detection.
    misses: u32,
    alpha: f64,
    rms: f64,
    support: usize,
}

/// The `jipda` preset (issue 17): people detections, then a CV Kalman filter per track with
/// JIPDA association and existence-based birth, confirmation and death.
///
/// - Association is soft: every detection in a track's gate moves it by its JIPDA weight
///   `β_ij` (the PDA update), and a frame where the person is not seen leaves the track
///   coasting on its velocity with a growing covariance, hence a growing gate.
/// - A track is born, tentative, at existence `jipda_birth` from a detection the tracks do not
///   explain (`Σ_i β_ij < 0.5`) and farther than `jipda_birth_exclusion` from every track (a
///   second fit of a tracked body starts no twin); it is reported once its existence reaches
///   `jipda_confirm` and deleted when it falls below `jipda_delete`. Of two tracks closer than
///   `jipda_merge_distance`, one is deleted (the tentative, then the undetected, then the
///   younger).
/// - A coasting track is reported with [`TrackStatus::Coasting`] and support 0 for at most
///   `jipda_max_coast_report` frames (it lives on, unreported, until its existence says it
///   is gone, and is reported again under its id once detected); every report
///   carries its existence and the 5 × 5 covariance of `[x, y, vx, vy, heading]` (heading
///   variance 1, as `kf-gnn`).
#[derive(Debug, Clone)]
pub struct JipdaPeopleTracker<C, R> {
    /// The contour detector (used when `legs` is `None`).
    pub detector: ContourDetector<C, R>,
    /// With `detector = legs`: the leg detector, used instead of `detector`.
    pub legs: Option<LegDetector>,
    inner: JpdaTracker,
    inner_cfg: JpdaTrackerConfig,
    r_icp: f64,
    min_travel: f64,
    max_coast_report: u32,
    extra: BTreeMap<u32, Extra>,
    t_last: Option<TimeUs>,
    last: Vec<LidarTrack>,
    withheld: Vec<LidarTrack>,
}

impl<C: Clusterer, R: Registration2> JipdaPeopleTracker<C, R> {
    /// A tracker with the `jipda_*` parameters of `cfg` ([`LidarPeopleConfig::jipda_tracker`]).
    pub fn new(
        detector: ContourDetector<C, R>,
        cfg: &LidarPeopleConfig,
    ) -> Result<Self, TrackerError> {
        let legs = leg_detector_of(cfg)?;
        let inner_cfg = cfg.jipda_tracker();
        let inner = JpdaTracker::new(inner_cfg)?;
        let min_travel = if legs.is_some() {
            cfg.leg_min_travel_m
        } else {
            0.0
        };
        Ok(Self {
            detector,
            legs,
            inner,
            inner_cfg,
            r_icp: cfg.r_icp,
            min_travel,
            max_coast_report: cfg.jipda_max_coast_report,
            extra: BTreeMap::new(),
            t_last: None,
            last: Vec::new(),
            withheld: Vec::new(),
        })
    }

    /// The rows of the last processed frame.
    pub fn last_rows(&self) -> &[LidarTrack] {
        &self.last
    }

    /// The rows the last frame held back: tracks detected in it but not reported, because
    /// they are not confirmed yet or have not walked `leg_min_travel_m` (`born` is false).
    /// An offline run can report them once their id is reported
    /// ([`RecordedRun::backfill`](super::RecordedRun::backfill)).
    pub fn last_withheld(&self) -> &[LidarTrack] {
        &self.withheld
    }

    /// The JIPDA tracker inside (its tracks, tentative ones included).
    pub fn inner(&self) -> &JpdaTracker {
        &self.inner
    }

    /// Processes one fused frame.
    pub fn process(
        &mut self,
        stamp: Stamp,
        frame: &FusedPoints,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        self.withheld.clear();
        let Some(pts) = frame_points(frame)? else {
            self.last.clear();
            return Ok(Vec::new());
        };
        let t = match self.t_last {
            Some(t0) if frame.t < t0 => t0,
            _ => frame.t,
        };
        self.t_last = Some(t);
        let dets = detect_people(&self.detector, self.legs.as_ref(), pts, self.r_icp)?;
        let z: Vec<[f64; 2]> = dets.iter().map(|d| [d.pose.x, d.pose.y]).collect();
        self.inner.advance(Stamp { t, ..stamp }, &z)?;

        let mut rows = Vec::new();
        let mut reports = Vec::new();
        let min_travel = self.min_travel;
        for tr in self.inner.tracks() {
            let id = tr.id.0;
            let pos = Point2::new(tr.est.mean[0], tr.est.mean[1]);
            let ex = self.extra.entry(id).or_insert(Extra {
                origin: pos,
                moved: min_travel <= 0.0,
                reported: false,
                misses: 0,
                alpha: 0.0,
                rms: f64::INFINITY,
                support: 0,
            });
            if let Some(d) = tr.best_detection.and_then(|j| dets.get(j)) {
                ex.alpha = d.pose.theta;
                ex.rms = d.rms;
                ex.support = d.support;
                // travel is measured on what was seen: a coasting estimate drifts on its
                // velocity, and static clutter whose track coasted 0.5 m away was reported
                // once seen again where it always was
                if !ex.moved && tr.detected {
                    ex.moved = (Point2::new(d.pose.x, d.pose.y) - ex.origin).norm() >= min_travel;
                }
            }
            ex.misses = if tr.detected { 0 } else { ex.misses + 1 };
            let coasting = !tr.detected;
            let row = LidarTrack {
                id,
                x: tr.est.mean[0],
                y: tr.est.mean[1],
                alpha: ex.alpha,
                vx: tr.est.mean[2],
                vy: tr.est.mean[3],
                support: if coasting { 0 } else { ex.support },
                rms: ex.rms,
                born: !ex.reported,
                gate_replaced: false,
            };
            let state = tr.state(&self.inner_cfg);
            if state != TrackState::Confirmed || !ex.moved {
                if tr.detected && state != TrackState::Deleted {
                    self.withheld.push(LidarTrack { born: false, ..row });
                }
                continue;
            }
            if ex.misses > self.max_coast_report {
                continue;
            }
            ex.reported = true;
            let mut r = report(stamp, &row, true);
            if coasting {
                r.status = TrackStatus::Coasting;
            }
            r.existence = Some(tr.existence);
            with_heading_cov(&mut r, &tr.est.cov);
            reports.push(r);
            rows.push(row);
        }
        // the tracks are in id order (born with increasing ids, deleted in place)
        let live: Vec<u32> = self.inner.tracks().iter().map(|t| t.id.0).collect();
        debug_assert!(live.windows(2).all(|w| w[0] < w[1]));
        self.extra.retain(|id, _| live.binary_search(id).is_ok());
        self.last = rows;
        Ok(reports)
    }
}

impl<C: Clusterer, R: Registration2> MultiTargetTracker for JipdaPeopleTracker<C, R> {
    type Input = FusedPoints;
    type Error = TrackerError;
    fn step(
        &mut self,
        stamp: Stamp,
        input: &FusedPoints,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        self.process(stamp, input)
    }
}

#[cfg(test)]
mod tests {
    use super::super::config::{Detector, Preset};
    use super::super::tracker::{DefaultLidarTracker, LidarPeopleTracker};
    use super::*;
    use crate::TrackerConfig;

    /// The near half of a torso ellipse centred at (cx, cy), 40 points.
    fn torso(cx: f64, cy: f64) -> Vec<Point2> {
        (0..40)
            .map(|i| {
                let a = std::f64::consts::PI * (1.0 + f64::from(i) / 40.0);
                Point2::new(cx + 0.22 * a.cos(), cy + 0.13 * a.sin())
            })
            .collect()
    }

    fn frame(k: u64, points: Vec<Point2>) -> FusedPoints {
        FusedPoints {
            t: TimeUs(50_000 * k as i64),
            points,
            no_data: false,
        }
    }

    /// Two legs at leg height: the near halves (6 points) of discs of radius 0.06 m centred at
    /// x = `a` and x = `b`, y = `y`.
    fn legs(a: f64, b: f64, y: f64) -> Vec<Point2> {
        let leg = move |x: f64| {
            (0..6).map(move |i| {
                let t = std::f64::consts::PI * (1.0 + f64::from(i) / 6.0);
                Point2::new(x + 0.06 * t.cos(), y + 0.06 * t.sin())
            })
        };
        leg(a).chain(leg(b)).collect()
    }

    /// The `jipda` preset with the leg detector.
    fn legs_cfg() -> LidarPeopleConfig {
        LidarPeopleConfig {
            detector: Detector::Legs,
            ..LidarPeopleConfig::preset(Preset::Jipda)
        }
    }

    #[test]
    fn one_walker_keeps_one_id_through_a_half_second_occlusion() {
        let cfg = LidarPeopleConfig::preset(Preset::Jipda);
        let mut tr = DefaultLidarTracker::from_config(&cfg).unwrap();
        let mut ids = std::collections::BTreeSet::new();
        let mut coasted = 0;
        let mut hidden = 0;
        let mut last_x = 0.0;
        for k in 0..80u64 {
            // 1.2 m/s along x; hidden for frames 40-49 (0.5 s)
            let x = 1.0 + 0.06 * k as f64;
            let pts = if (40..50).contains(&k) {
                Vec::new()
            } else {
                torso(x, 3.0)
            };
            let reps = tr.step(Stamp::from_frame(k, 0.05), &frame(k, pts)).unwrap();
            assert!(reps.len() <= 1, "frame {k}: {} tracks", reps.len());
            if k > 20 && reps.is_empty() {
                hidden += 1;
            }
            for r in &reps {
                ids.insert(r.id);
                assert!(r.existence.is_some_and(|e| (0.0..=1.0).contains(&e)));
                if r.status == TrackStatus::Coasting {
                    coasted += 1;
                }
                last_x = tr.last_rows()[0].x;
            }
        }
        assert_eq!(ids.len(), 1, "one id for one walker: {ids:?}");
        // the first two frames of the occlusion are reported as coasting (jipda_max_coast_report),
        // the other eight not; the track lives on and comes back under its id
        assert_eq!(coasted, 2, "coasting reports");
        assert_eq!(hidden, 8, "unreported frames");
        let x_end = 1.0 + 0.06 * 79.0;
        assert!(
            (last_x - x_end).abs() < 0.1,
            "ends at {last_x}, truth {x_end}"
        );
    }

    #[test]
    fn a_track_that_stays_unseen_is_deleted() {
        let cfg = LidarPeopleConfig::preset(Preset::Jipda);
        let mut tr = DefaultLidarTracker::from_config(&cfg).unwrap();
        for k in 0..20u64 {
            tr.step(Stamp::from_frame(k, 0.05), &frame(k, torso(2.0, 3.0)))
                .unwrap();
        }
        assert_eq!(tr.last_rows().len(), 1);
        for k in 20..60u64 {
            tr.step(Stamp::from_frame(k, 0.05), &frame(k, Vec::new()))
                .unwrap();
        }
        assert!(tr.last_rows().is_empty());
        let LidarPeopleTracker::Jipda(j) = &tr else {
            panic!("the jipda preset builds the jipda tracker");
        };
        assert!(j.inner().tracks().is_empty(), "deleted, not only hidden");
    }

    #[test]
    fn two_people_apart_get_two_ids_and_nan_is_an_error() {
        let cfg = LidarPeopleConfig::preset(Preset::Jipda);
        let mut tr = DefaultLidarTracker::from_config(&cfg).unwrap();
        let mut n = 0;
        for k in 0..20u64 {
            let mut pts = torso(2.0 + 0.05 * k as f64, 3.0);
            pts.extend(torso(2.0 + 0.05 * k as f64, 5.0));
            n = tr
                .step(Stamp::from_frame(k, 0.05), &frame(k, pts))
                .unwrap()
                .len();
        }
        assert_eq!(n, 2);
        let bad = frame(20, vec![Point2::new(f64::NAN, 1.0)]);
        assert!(tr.step(Stamp::from_frame(20, 0.05), &bad).is_err());
        // a frame stamped before the last one is taken as simultaneous, not an error
        let early = frame(3, torso(3.0, 3.0));
        assert!(tr.step(Stamp::from_frame(21, 0.05), &early).is_ok());
    }

    #[test]
    fn with_legs_a_standing_pair_is_not_reported_until_it_walks() {
        let mut tr = DefaultLidarTracker::from_config(&legs_cfg()).unwrap();
        let mut reported_while_standing = 0;
        for k in 0..30u64 {
            let pts = legs(2.0, 2.3, 3.0);
            reported_while_standing += tr
                .step(Stamp::from_frame(k, 0.05), &frame(k, pts))
                .unwrap()
                .len();
        }
        assert_eq!(reported_while_standing, 0);
        let mut seen = 0;
        for k in 30..60u64 {
            let x = 2.0 + 0.06 * (k - 30) as f64;
            let pts = legs(x, x + 0.3, 3.0);
            seen += tr
                .step(Stamp::from_frame(k, 0.05), &frame(k, pts))
                .unwrap()
                .len();
        }
        assert!(seen > 10, "reported once it walked ({seen} frames)");
    }

    /// The 0.5 m travel rule looks at the detections a track takes, not at its estimate: a
    /// standing pair whose detection jitters once (a spurious velocity), then is unseen for 15
    /// frames while its track coasts away on that velocity, and is then seen again where it
    /// stood, is never reported.
    #[test]
    fn with_legs_a_coasting_drift_is_not_travel() {
        let mut tr = DefaultLidarTracker::from_config(&legs_cfg()).unwrap();
        let pair = |cx: f64| legs(cx, cx + 0.3, 3.0);
        let mut reported = 0;
        let mut max_drift: f64 = 0.0;
        for k in 0..70u64 {
            let pts = match k {
                10 | 11 => pair(2.0 + 0.15 * (k - 9) as f64),
                12..=26 => Vec::new(),
                _ => pair(2.0),
            };
            reported += tr
                .step(Stamp::from_frame(k, 0.05), &frame(k, pts))
                .unwrap()
                .len();
            let LidarPeopleTracker::Jipda(j) = &tr else {
                panic!("the jipda preset builds the jipda tracker");
            };
            for t in j.inner().tracks() {
                max_drift = max_drift.max((t.est.mean[0] - 2.15).abs());
            }
        }
        assert!(
            max_drift > 0.6,
            "the test needs a coasting drift ({max_drift:.2} m)"
        );
        assert_eq!(reported, 0, "static clutter reported");
    }

    /// A person who stands for 30 frames, then walks: the travel rule holds their track back
    /// while they stand, and the held-back rows are there for an offline backfill, which then
    /// reports the track from its first detection on; static clutter beside them is held back
    /// too but never reported, so never backfilled. Both trackers that hold tracks back.
    #[test]
    fn with_legs_a_standing_person_is_backfilled_and_clutter_is_not() {
        use super::super::{RecordedFrame, RecordedRun};
        for preset in [Preset::Jipda, Preset::KfGnn] {
            let cfg = LidarPeopleConfig {
                detector: Detector::Legs,
                ..LidarPeopleConfig::preset(preset)
            };
            let mut tr = DefaultLidarTracker::from_config(&cfg).unwrap();
            let mut run = RecordedRun::default();
            for k in 0..60u64 {
                let x = if k < 30 {
                    2.0
                } else {
                    2.0 + 0.06 * (k - 29) as f64
                };
                let mut pts = legs(x, x + 0.3, 3.0);
                pts.extend(legs(-2.0, -1.7, 1.0)); // clutter: a leg pair that never moves
                tr.step(Stamp::from_frame(k, 0.05), &frame(k, pts)).unwrap();
                run.frames.push(RecordedFrame {
                    t: TimeUs(50_000 * k as i64),
                    dynamic: 0,
                    tracks: tr.last_rows().to_vec(),
                    withheld: tr.last_withheld().to_vec(),
                });
            }
            let first_report = |run: &RecordedRun| {
                run.frames
                    .iter()
                    .position(|f| !f.tracks.is_empty())
                    .unwrap()
            };
            let online = first_report(&run);
            assert!(
                online >= 30,
                "{preset:?}: reported at {online}, while standing"
            );
            let held: usize = run.frames[..online].iter().map(|f| f.withheld.len()).sum();
            assert!(
                held >= 2 * 25,
                "{preset:?}: {held} rows held back (person and clutter)"
            );
            let added = run.backfill();
            let offline = first_report(&run);
            assert!(offline <= 5, "{preset:?}: backfilled from {offline}");
            assert!(added >= online - offline, "{preset:?}: {added} rows added");
            // one id, the person's, in every frame from `offline` on; the clutter never
            let ids: std::collections::BTreeSet<u32> = run
                .frames
                .iter()
                .flat_map(|f| f.tracks.iter().map(|t| t.id))
                .collect();
            assert_eq!(ids.len(), 1, "{preset:?}: {ids:?}");
            for f in &run.frames[offline..] {
                assert_eq!(f.tracks.len(), 1, "{preset:?}");
                assert!(
                    f.tracks[0].x > 1.5,
                    "{preset:?}: the clutter was backfilled"
                );
                assert!(f.withheld.is_empty());
            }
            assert!(run.frames[offline].tracks[0].born);
            let borns = run
                .frames
                .iter()
                .flat_map(|f| &f.tracks)
                .filter(|t| t.born)
                .count();
            assert_eq!(borns, 1, "{preset:?}");
        }
    }

    /// Two walkers pass each other 0.3 m apart (as on positive_3 at t = 20.5 s), and the
    /// nearer hides the farther for 3 frames as they pass: with legs (no merging,
    /// `leg_merge_distance` = 0) both keep their ids; with the contour detector's merge distance
    /// of 0.25 m the two coasting tracks are taken for one person tracked twice and one id
    /// ends.
    #[test]
    fn with_legs_two_walkers_passing_close_keep_their_ids() {
        let pair = |cx: f64, cy: f64| legs(cx - 0.1, cx + 0.1, cy);
        let run = |merge: f64| {
            let cfg = LidarPeopleConfig {
                leg_merge_distance: merge,
                ..legs_cfg()
            };
            let mut tr = DefaultLidarTracker::from_config(&cfg).unwrap();
            let mut ids = std::collections::BTreeSet::new();
            let mut last = Vec::new();
            for k in 0..90u64 {
                // A along +x at y = 3.0, B along -x at y = 3.3; they meet at k = 45
                let (xa, xb) = (0.3 + 0.06 * k as f64, 5.7 - 0.06 * k as f64);
                let mut pts = pair(xa, 3.0);
                if !(44..47).contains(&k) {
                    pts.extend(pair(xb, 3.3));
                }
                let reps = tr.step(Stamp::from_frame(k, 0.05), &frame(k, pts)).unwrap();
                ids.extend(reps.iter().map(|r| r.id));
                last = tr.last_rows().to_vec();
            }
            (ids.len(), last)
        };
        let (n, last) = run(0.0);
        assert_eq!(n, 2, "two walkers, two ids");
        assert_eq!(last.len(), 2);
        for (x, y) in [(0.3 + 0.06 * 89.0, 3.0), (5.7 - 0.06 * 89.0, 3.3)] {
            assert!(
                last.iter()
                    .any(|t| (t.x - x).abs() < 0.2 && (t.y - y).abs() < 0.15),
                "no track at ({x:.2}, {y}): {last:?}"
            );
        }
        let (merged, _) = run(0.25);
        assert!(
            merged > 2,
            "the merge rule must be what the test exercises ({merged} ids)"
        );
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(128))]
        /// Any finite frames (people-like arcs, scattered points, empty and no-data frames,
        /// stamps that jump or go backwards), with either detector: a result, never a panic;
        /// every report is a confirmed or coasting track with ψ in [0, 1], distinct ids, and
        /// rows that match the reports.
        #[test]
        fn never_panics_and_reports_are_consistent(
            legs in proptest::bool::ANY,
            frames in proptest::collection::vec(
                (
                    proptest::collection::vec((-20.0..20.0f64, -20.0..20.0f64), 0..60),
                    proptest::collection::vec((0.5..9.5f64, 0.5..7.5f64), 0..4),
                    -200_000i64..400_000,
                    proptest::bool::weighted(0.1),
                ),
                1..40,
            ),
        ) {
            let cfg = LidarPeopleConfig {
                detector: if legs { Detector::Legs } else { Detector::Contour },
                ..LidarPeopleConfig::preset(Preset::Jipda)
            };
            let mut tr = DefaultLidarTracker::from_config(&cfg).unwrap();
            let mut t = 0i64;
            for (k, (scatter, people, dt, no_data)) in frames.into_iter().enumerate() {
                t += dt;
                let mut points: Vec<Point2> =
                    scatter.into_iter().map(|(x, y)| Point2::new(x, y)).collect();
                for (x, y) in people {
                    points.extend(torso(x, y));
                }
                let f = FusedPoints { t: TimeUs(t), points, no_data };
                let reps = tr.step(Stamp::from_frame(k as u64, 0.05), &f).unwrap();
                let rows = tr.last_rows();
                proptest::prop_assert_eq!(rows.len(), reps.len());
                let mut ids: Vec<_> = reps.iter().map(|r| r.id).collect();
                ids.sort_unstable();
                ids.dedup();
                proptest::prop_assert_eq!(ids.len(), reps.len());
                for (r, row) in reps.iter().zip(rows) {
                    proptest::prop_assert_eq!(r.id.0, row.id);
                    proptest::prop_assert!(matches!(r.status, TrackStatus::Confirmed | TrackStatus::Coasting));
                    proptest::prop_assert!(r.existence.is_some_and(|e| (0.0..=1.0).contains(&e)));
                    proptest::prop_assert!(row.x.is_finite() && row.y.is_finite());
                }
            }
        }
    }
}
