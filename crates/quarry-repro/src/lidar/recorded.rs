//! The lidar tracker on the leg-tracker recordings (`shared/data/leg-tracker`): the position
//! error of a recorded run against the labelled leg centroids.

use quarry_core::CoreError;
use quarry_data::leg_labels::LabelledPerson;
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
