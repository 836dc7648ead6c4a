//! The measures of spec 003 §4: the paper's per-frame success rate, the localisation error, and
//! the standard MOT metrics (through quarry-eval) over the same frames.

use crate::ReproError;
use nalgebra::Vector2;
use quarry_assoc::{PositionVelocityGate, PvState};
use quarry_core::{CoreError, TimeUs};
use quarry_eval::mot::{Frame, evaluate};
use quarry_eval::{Euclidean, hungarian_match};
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, HashSet};

/// One evaluated frame: ground truth and reported tracks.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EvalFrame {
    /// Frame time t_f.
    pub t: TimeUs,
    /// GT people: id, position, total number of beams hitting them (all scanners).
    pub gt: Vec<(u32, [f64; 2], usize)>,
    /// Reported tracks: id, position.
    pub tracks: Vec<(u32, [f64; 2])>,
}

/// Localisation statistics over matched pairs.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LocStats {
    /// Matched pairs.
    pub n: usize,
    /// Mean Euclidean error, metres (the paper's "about 18 cm").
    pub mean: f64,
    /// RMSE, metres.
    pub rmse: f64,
    /// Median, metres.
    pub median: f64,
    /// 95th percentile, metres.
    pub p95: f64,
}

/// Everything §4 asks for, for one run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Paper003Metrics {
    /// Evaluated frames.
    pub frames: usize,
    /// Frames with S(f) = 1 (the paper's success).
    pub success: usize,
    /// Frames where every person has at least `min_num_point` beams in total.
    pub detectable_frames: usize,
    /// Successful frames among the detectable ones.
    pub success_detectable: usize,
    /// Frames with S_strict(f) = 1.
    pub strict_success: usize,
    /// Localisation over Hungarian-matched pairs within d_match.
    pub loc: LocStats,
    /// CLEAR MOTA.
    pub mota: f64,
    /// CLEAR MOTP (mean matched distance, metres).
    pub motp: f64,
    /// IDF1.
    pub idf1: f64,
    /// HOTA (mean over α).
    pub hota: f64,
    /// DetA.
    pub deta: f64,
    /// AssA.
    pub assa: f64,
    /// LocA.
    pub loca: f64,
    /// Identity switches.
    pub idsw: usize,
    /// False positives.
    pub fp: usize,
    /// Misses.
    pub fn_: usize,
    /// GT objects (sum over frames).
    pub gt_total: usize,
}

impl Paper003Metrics {
    /// Success rate S (fraction).
    pub fn success_rate(&self) -> f64 {
        ratio(self.success, self.frames)
    }
    /// Success rate restricted to detectable frames.
    pub fn success_rate_detectable(&self) -> f64 {
        ratio(self.success_detectable, self.detectable_frames)
    }
    /// Strict success rate.
    pub fn strict_rate(&self) -> f64 {
        ratio(self.strict_success, self.frames)
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 { 0.0 } else { a as f64 / b as f64 }
}

/// Localisation statistics of a list of errors.
pub fn loc_stats(errs: &mut [f64]) -> LocStats {
    if errs.is_empty() {
        return LocStats::default();
    }
    errs.sort_by(f64::total_cmp);
    let n = errs.len();
    let mean = errs.iter().sum::<f64>() / n as f64;
    let rmse = (errs.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
    let q = |p: f64| errs[((p * (n - 1) as f64).round() as usize).min(n - 1)];
    LocStats {
        n,
        mean,
        rmse,
        median: q(0.5),
        p95: q(0.95),
    }
}

/// The paper's success S(f) for every frame (spec §4): (1) as many tracks as GT people, (2) every
/// track reported at f−1 and f passes gate (8) between its reports (velocity terms only when also
/// reported at f−2), (3) no more new track ids than GT people appearing at f.
pub fn paper_success(frames: &[EvalFrame], gate: &PositionVelocityGate) -> Vec<bool> {
    let mut out = Vec::with_capacity(frames.len());
    let mut prev: HashMap<u32, [f64; 2]> = HashMap::new();
    let mut prev2: HashMap<u32, [f64; 2]> = HashMap::new();
    let mut seen_tracks: HashSet<u32> = HashSet::new();
    let mut prev_gt: HashSet<u32> = HashSet::new();
    let mut t_prev: Option<TimeUs> = None;
    let mut t_prev2: Option<TimeUs> = None;
    for f in frames {
        let c1 = f.tracks.len() == f.gt.len();
        let mut c2 = true;
        let dt = t_prev.map_or(0.05, |t0| f.t.secs_since(t0));
        let dt_prev = match (t_prev, t_prev2) {
            (Some(a), Some(b)) => a.secs_since(b),
            _ => 0.05,
        };
        for (id, p) in &f.tracks {
            if let Some(p1) = prev.get(id) {
                let v_cur = Vector2::new(p[0] - p1[0], p[1] - p1[1]) / dt;
                let v_prev = prev2
                    .get(id)
                    .map(|p2| Vector2::new(p1[0] - p2[0], p1[1] - p2[1]) / dt_prev);
                let a = PvState {
                    pos: Vector2::new(p1[0], p1[1]),
                    vel: v_prev,
                };
                let b = PvState {
                    pos: Vector2::new(p[0], p[1]),
                    vel: v_prev.map(|_| v_cur),
                };
                if gate.eq8(&a, &b, dt) > 1.0 {
                    c2 = false;
                }
            }
        }
        let new_ids = f
            .tracks
            .iter()
            .filter(|(id, _)| !seen_tracks.contains(id))
            .count();
        let gt_new =
            f.gt.iter()
                .filter(|(id, _, _)| !prev_gt.contains(id))
                .count();
        let c3 = new_ids <= gt_new;
        out.push(c1 && c2 && c3);
        prev2 = std::mem::take(&mut prev);
        prev = f.tracks.iter().map(|(id, p)| (*id, *p)).collect();
        seen_tracks.extend(f.tracks.iter().map(|(id, _)| *id));
        prev_gt = f.gt.iter().map(|(id, _, _)| *id).collect();
        t_prev2 = t_prev;
        t_prev = Some(f.t);
    }
    out
}

/// All the §4 measures over `frames` (the evaluation window), with the gate of §3 and the
/// `min_num_point` and `d_match` thresholds.
pub fn evaluate_paper003(
    frames: &[EvalFrame],
    gate: &PositionVelocityGate,
    min_num_point: usize,
    d_match: f64,
) -> Result<Paper003Metrics, ReproError> {
    if !(d_match.is_finite() && d_match > 0.0) {
        return Err(CoreError::invalid("d_match", "must be finite and > 0").into());
    }
    let success = paper_success(frames, gate);
    let mut m = Paper003Metrics {
        frames: frames.len(),
        ..Default::default()
    };
    let mut errs = Vec::new();
    // CLEAR mapping for the strict rule: last matched track of each GT id
    let mut last_match: HashMap<u32, u32> = HashMap::new();
    for (f, ok) in frames.iter().zip(&success) {
        let detectable = f.gt.iter().all(|(_, _, n)| *n >= min_num_point);
        m.detectable_frames += usize::from(detectable);
        m.success += usize::from(*ok);
        m.success_detectable += usize::from(*ok && detectable);
        let gt: Vec<[f64; 2]> = f.gt.iter().map(|g| g.1).collect();
        let tr: Vec<[f64; 2]> = f.tracks.iter().map(|t| t.1).collect();
        let pairs = match_within(&gt, &tr, d_match)?;
        let mut all_matched = pairs.len() == gt.len();
        for &(gi, ti, d) in &pairs {
            errs.push(d);
            let gid = f.gt[gi].0;
            let tid = f.tracks[ti].0;
            if let Some(prev) = last_match.insert(gid, tid)
                && prev != tid
            {
                all_matched = false; // identity switch
            }
        }
        m.strict_success += usize::from(*ok && all_matched);
    }
    m.loc = loc_stats(&mut errs);
    let mot_frames: Vec<Frame<[f64; 2]>> = frames
        .iter()
        .map(|f| Frame {
            gt: f.gt.iter().map(|g| (i64::from(g.0), g.1)).collect(),
            hyp: f.tracks.iter().map(|t| (i64::from(t.0), t.1)).collect(),
        })
        .collect();
    let sim = Euclidean::new(d_match)?;
    let s = evaluate(&mot_frames, &sim)?;
    m.mota = s.clear.mota().unwrap_or(0.0);
    m.motp = s.clear.motp().unwrap_or(0.0);
    m.idf1 = s.identity.idf1().unwrap_or(0.0);
    m.hota = s.hota.hota_mean();
    m.deta = s.hota.deta_mean();
    m.assa = s.hota.assa_mean();
    m.loca = s.hota.loca_mean();
    m.idsw = s.clear.num_switches;
    m.fp = s.clear.num_false_positives;
    m.fn_ = s.clear.num_misses;
    m.gt_total = s.clear.num_objects;
    Ok(m)
}

/// Hungarian matching on Euclidean cost allowing only pairs within `d_max`: `(gt, track, dist)`.
pub fn match_within(
    gt: &[[f64; 2]],
    tr: &[[f64; 2]],
    d_max: f64,
) -> Result<Vec<(usize, usize, f64)>, ReproError> {
    if gt.is_empty() || tr.is_empty() {
        return Ok(Vec::new());
    }
    let d = |a: &[f64; 2], b: &[f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let mut cost = Vec::with_capacity(gt.len() * tr.len());
    for g in gt {
        for t in tr {
            cost.push(d(g, t));
        }
    }
    let pairs = hungarian_match(&cost, gt.len(), tr.len(), d_max)?;
    Ok(pairs
        .into_iter()
        .map(|(i, j)| (i, j, d(&gt[i], &tr[j])))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(k: i64, gt: &[(u32, f64)], tr: &[(u32, f64)]) -> EvalFrame {
        EvalFrame {
            t: TimeUs(k * 50_000),
            gt: gt.iter().map(|&(i, x)| (i, [x, 1.0], 20)).collect(),
            tracks: tr.iter().map(|&(i, x)| (i, [x, 1.0])).collect(),
        }
    }

    #[test]
    fn success_rules() {
        let g = PositionVelocityGate::spec003();
        // a person walking 5 cm per frame, tracked by one id: all frames succeed
        let fs: Vec<EvalFrame> = (0..10)
            .map(|k| frame(k, &[(1, 0.05 * k as f64)], &[(7, 0.05 * k as f64 + 0.01)]))
            .collect();
        assert!(paper_success(&fs, &g).iter().all(|&s| s));
        // a jump of 0.3 m (> k σ = 0.22 m) fails that frame only
        let mut fs2 = fs.clone();
        fs2[5].tracks[0].1[0] += 0.3;
        let s = paper_success(&fs2, &g);
        assert!(!s[5] && !s[6] && s[4] && s[8]);
        // a new id at frame 3 (replacement) fails frame 3 (rule 3)
        let mut fs3 = fs.clone();
        for f in &mut fs3[3..] {
            f.tracks[0].0 = 8;
        }
        let s = paper_success(&fs3, &g);
        assert!(!s[3] && s[4]);
        // a missing track fails (rule 1)
        let mut fs4 = fs;
        fs4[2].tracks.clear();
        assert!(!paper_success(&fs4, &g)[2]);
    }

    #[test]
    fn metrics_on_perfect_and_offset_tracks() {
        let g = PositionVelocityGate::spec003();
        let fs: Vec<EvalFrame> = (0..20)
            .map(|k| {
                let x = 0.05 * k as f64;
                frame(k, &[(1, x), (2, x + 3.0)], &[(5, x + 0.1), (6, x + 3.0)])
            })
            .collect();
        let m = evaluate_paper003(&fs, &g, 8, 0.5).unwrap();
        assert_eq!(m.success, 20);
        assert_eq!(m.loc.n, 40);
        assert!((m.loc.mean - 0.05).abs() < 1e-12);
        assert!((m.loc.rmse - (0.005f64).sqrt()).abs() < 1e-12);
        assert!((m.mota - 1.0).abs() < 1e-12);
        assert!((m.idf1 - 1.0).abs() < 1e-12);
        assert_eq!(m.strict_success, 20);
        let mut e = vec![0.3, 0.1, 0.2];
        let l = loc_stats(&mut e);
        assert!((l.median - 0.2).abs() < 1e-12);
    }
}
