//! The lidar tracker on the leg-tracker recordings (`shared/data/leg-tracker`): the position
//! error of a recorded run against the labelled leg centroids, scored two ways:
//! - [`score_labelled`]: the recordings' own definition, one person per scan at the mean of
//!   every labelled leg;
//! - [`score_label_groups`]: each scan's legs split into the people they belong to
//!   ([`LabelledScan::groups`]), each person scored on its own, and the best score any tracker
//!   of people can reach under the first definition.

use quarry_core::CoreError;
use quarry_data::leg_labels::{LabelledPerson, LabelledScan};
use quarry_trackers::lidar_people::RecordedRun;

use crate::Result;

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

/// Root mean square of `v`; NaN when empty.
fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt()
    }
}

/// Scores `run` against `labels`: for each labelled stamp present in the run, the nearest track
/// within `match_radius` (metres, finite and > 0) is the match. Labels whose stamp is not in
/// the run are ignored.
pub fn score_labelled(
    run: &RecordedRun,
    labels: &[LabelledPerson],
    match_radius: f64,
) -> Result<LabelledError> {
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

/// A recorded run scored against the labels split into people ([`score_label_groups`]).
///
/// The leg-tracker recordings label every leg-sized cluster within ±15° and 5 m of the laser,
/// so a second walker in that wedge is labelled too, and the recordings' person (the mean of
/// every label, [`score_labelled`]) then lies between two people. This score counts each group
/// of legs as a person, and says how far the recordings' definition lets any tracker get.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct LabelGroupScore {
    /// Labelled scans found in the run (as [`LabelledError::labelled`]).
    pub labelled: usize,
    /// Of those, scans whose legs form more than one group.
    pub multi_group_scans: usize,
    /// Groups (people) in the labelled scans found in the run.
    pub groups: usize,
    /// Groups with a track within the match radius, each track counted for at most one group
    /// of its scan (nearest pairs first).
    pub matched: usize,
    /// RMSE of the matched groups, metres.
    pub rmse_m: f64,
    /// Labelled scans that a tracker reporting every group exactly at its legs' mean would
    /// match under the recordings' definition ([`score_labelled`]): the most any tracker of
    /// people can match there. Below `labelled` when a scan's groups lie so far apart that
    /// none is within the match radius of their common mean.
    pub ceiling_matched: usize,
    /// RMSE of that ideal tracker's matched scans under the recordings' definition, metres.
    pub ceiling_rmse_m: f64,
}

/// Scores `run` against `scans` with each scan's legs split into people: single-linkage groups
/// within `link_m` ([`LabelledScan::groups`]; leg_tracker's `max_leg_pairing_dist`, 0.8 m, is
/// the natural value). For each labelled stamp present in the run, groups and tracks are
/// paired nearest first within `match_radius` (metres), one track per group. Labels whose
/// stamp is not in the run are ignored.
///
/// ```
/// use quarry_core::{Point2, TimeUs};
/// use quarry_data::leg_labels::LabelledScan;
/// use quarry_repro::lidar::score_label_groups;
/// use quarry_trackers::lidar_people::{LidarTrack, RecordedFrame, RecordedRun};
/// let track = |x: f64| LidarTrack {
///     id: 1, x, y: 0.0, alpha: 0.0, vx: 0.0, vy: 0.0, support: 0, rms: 0.0,
///     born: false, gate_replaced: false,
/// };
/// // two people 3 m apart, each with a track on them; their common mean is 1.5 m from both
/// let run = RecordedRun {
///     frames: vec![RecordedFrame {
///         t: TimeUs(0), dynamic: 0, tracks: vec![track(1.0), track(4.0)], withheld: vec![],
///     }],
///     ..RecordedRun::default()
/// };
/// let labels = [LabelledScan { t: TimeUs(0), legs: vec![Point2::new(1.0, 0.0), Point2::new(4.0, 0.0)] }];
/// let s = score_label_groups(&run, &labels, 0.5, 0.8)?;
/// assert_eq!((s.groups, s.matched, s.multi_group_scans), (2, 2, 1));
/// assert_eq!(s.ceiling_matched, 0); // no tracker of people is near the mean at 2.5 m
/// # Ok::<(), quarry_repro::ReproError>(())
/// ```
///
/// # Errors
/// `match_radius` or `link_m` not finite and positive.
pub fn score_label_groups(
    run: &RecordedRun,
    scans: &[LabelledScan],
    match_radius: f64,
    link_m: f64,
) -> Result<LabelGroupScore> {
    if !(match_radius.is_finite() && match_radius > 0.0) {
        return Err(CoreError::invalid("match_radius", "must be finite and > 0").into());
    }
    if !(link_m.is_finite() && link_m > 0.0) {
        return Err(CoreError::invalid("link_m", "must be finite and > 0").into());
    }
    let mut out = LabelGroupScore::default();
    let (mut errs, mut ceiling) = (Vec::new(), Vec::new());
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for s in scans {
        let Ok(i) = run.frames.binary_search_by_key(&s.t, |f| f.t) else {
            continue;
        };
        if s.legs.is_empty() {
            continue;
        }
        out.labelled += 1;
        let groups = s.groups(link_m)?;
        out.groups += groups.len();
        if groups.len() > 1 {
            out.multi_group_scans += 1;
        }
        let mean = s.person().pos;
        let best = groups
            .iter()
            .map(|g| (g.pos.x - mean.x).hypot(g.pos.y - mean.y))
            .fold(f64::INFINITY, f64::min);
        if best <= match_radius {
            ceiling.push(best);
        }
        let tracks = &run.frames[i].tracks;
        pairs.clear();
        for (gi, g) in groups.iter().enumerate() {
            for (ti, t) in tracks.iter().enumerate() {
                let d = (t.x - g.pos.x).hypot(t.y - g.pos.y);
                if d <= match_radius {
                    pairs.push((d, gi, ti));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let (mut g_used, mut t_used) = (vec![false; groups.len()], vec![false; tracks.len()]);
        for &(d, gi, ti) in &pairs {
            if !g_used[gi] && !t_used[ti] {
                g_used[gi] = true;
                t_used[ti] = true;
                errs.push(d);
            }
        }
    }
    out.matched = errs.len();
    out.rmse_m = rms(&errs);
    out.ceiling_matched = ceiling.len();
    out.ceiling_rmse_m = rms(&ceiling);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use quarry_core::{Point2, TimeUs};
    use quarry_trackers::lidar_people::{LidarTrack, RecordedFrame};

    fn track(x: f64, y: f64) -> LidarTrack {
        LidarTrack {
            id: 1,
            x,
            y,
            alpha: 0.0,
            vx: 0.0,
            vy: 0.0,
            support: 0,
            rms: 0.0,
            born: false,
            gate_replaced: false,
        }
    }

    #[test]
    fn a_track_counts_for_one_group_only() {
        // two groups 0.9 m apart, one track between them 0.45 m from each
        let run = RecordedRun {
            frames: vec![RecordedFrame {
                t: TimeUs(5),
                dynamic: 0,
                tracks: vec![track(0.45, 0.0)],
                withheld: Vec::new(),
            }],
            ..RecordedRun::default()
        };
        let labels = [LabelledScan {
            t: TimeUs(5),
            legs: vec![Point2::new(0.0, 0.0), Point2::new(0.9, 0.0)],
        }];
        let s = score_label_groups(&run, &labels, 0.5, 0.8).unwrap();
        assert_eq!((s.labelled, s.groups, s.matched), (1, 2, 1));
        assert!((s.rmse_m - 0.45).abs() < 1e-12);
        // their mean (0.45) is 0.45 m from either group: an exact tracker of people matches it
        assert_eq!(s.ceiling_matched, 1);
        // a stamp not in the run is ignored; bad radii are refused
        let other = [LabelledScan {
            t: TimeUs(6),
            legs: vec![Point2::new(0.0, 0.0)],
        }];
        assert_eq!(
            score_label_groups(&run, &other, 0.5, 0.8).unwrap().labelled,
            0
        );
        for bad in [0.0, -0.5, f64::NAN, f64::INFINITY] {
            assert!(score_label_groups(&run, &labels, bad, 0.8).is_err());
            assert!(score_label_groups(&run, &labels, 0.5, bad).is_err());
        }
    }

    proptest::proptest! {
        /// A run whose tracks sit exactly on every group scores every group, with zero error,
        /// and [`score_labelled`] gives it exactly the ceiling: the ceiling is what it claims.
        #[test]
        fn a_tracker_on_every_group_reaches_the_ceiling(
            scans in proptest::collection::vec(
                proptest::collection::vec((-6.0f64..6.0, -6.0f64..6.0), 1..8), 1..12),
            radius in 0.1f64..2.0,
            link in 0.1f64..2.0,
        ) {
            let labels: Vec<LabelledScan> = scans
                .iter()
                .enumerate()
                .map(|(k, legs)| LabelledScan {
                    t: TimeUs(k as i64 * 100),
                    legs: legs.iter().map(|&(x, y)| Point2::new(x, y)).collect(),
                })
                .collect();
            let run = RecordedRun {
                frames: labels
                    .iter()
                    .map(|l| RecordedFrame {
                        t: l.t,
                        dynamic: 0,
                        tracks: l
                            .groups(link)
                            .unwrap()
                            .iter()
                            .map(|g| track(g.pos.x, g.pos.y))
                            .collect(),
                        withheld: Vec::new(),
                    })
                    .collect(),
                ..RecordedRun::default()
            };
            let g = score_label_groups(&run, &labels, radius, link).unwrap();
            proptest::prop_assert_eq!(g.labelled, labels.len());
            proptest::prop_assert_eq!(g.matched, g.groups);
            proptest::prop_assert!(g.rmse_m == 0.0);
            let people: Vec<LabelledPerson> = labels.iter().map(LabelledScan::person).collect();
            let e = score_labelled(&run, &people, radius).unwrap();
            proptest::prop_assert_eq!(e.matched, g.ceiling_matched);
            if e.matched > 0 {
                proptest::prop_assert!((e.rmse_m - g.ceiling_rmse_m).abs() < 1e-12);
            }
        }
    }
}
