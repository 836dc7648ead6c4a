//! Multi-object tracking metrics: CLEAR MOT ([`clear_mot`]), the identity measures
//! ([`idf1`]) and HOTA ([`hota`]), generic over how objects are compared ([`Similarity`]).
//!
//! The numbers agree with the reference implementations to 1e-6 (checked on fixtures whose
//! values were computed with py-motmetrics 1.4.0 and TrackEval 1.3.0):
//! - CLEAR MOT follows **py-motmetrics** (`MOTAccumulator.update`): a ground-truth object keeps
//!   the hypothesis it was last matched to (in any earlier frame) whenever that pair is still
//!   within the threshold; the remaining pairs are matched by minimum total distance; an identity
//!   switch is counted when an object is matched to a hypothesis other than the one it was last
//!   matched to. MOTP is py-motmetrics' mean *distance* of matched pairs (`1 - IoU` for boxes,
//!   metres for points); [`ClearMot::motchallenge_motp`] gives the MOTChallenge percentage
//!   (mean IoU x 100).
//! - IDF1 follows Ristani et al. 2016 (identical in py-motmetrics and TrackEval): one global
//!   one-to-one matching of trajectories maximising the number of frames in which the matched
//!   pair is within the threshold.
//! - HOTA follows **TrackEval** (`metrics/hota.py`): alpha = 0.05, 0.10, ..., 0.95, one
//!   per-frame assignment maximising `global alignment score x similarity`, then thresholded at
//!   each alpha; the reported HOTA, DetA, AssA and LocA are the means over the 19 alphas.
//!
//! Both tools call SciPy's assignment solver; [`crate::lsap`] is an exact port of it, so ties
//! are broken the same way.
//!
//! ```
//! use quarry_eval::mot::{evaluate, Frame};
//! use quarry_eval::similarity::Iou;
//! let gt = vec![(1, [0.0, 0.0, 10.0, 10.0]), (2, [50.0, 0.0, 10.0, 10.0])];
//! let frames = vec![
//!     Frame { gt: gt.clone(), hyp: vec![(7, [1.0, 0.0, 10.0, 10.0]), (8, [50.0, 0.0, 10.0, 10.0])] },
//!     Frame { gt: gt.clone(), hyp: vec![(8, [1.0, 0.0, 10.0, 10.0])] },  // 8 jumps to object 1
//! ];
//! let s = evaluate(&frames, &Iou::default())?;
//! assert_eq!((s.clear.num_misses, s.clear.num_false_positives, s.clear.num_switches), (1, 0, 1));
//! assert!((s.clear.mota().unwrap() - 0.5).abs() < 1e-12);
//! # Ok::<(), quarry_eval::EvalError>(())
//! ```

use std::collections::{HashMap, HashSet};

use quarry_core::CoreError;

use crate::EvalError;
use crate::lsap::{assign_with_forbidden, linear_sum_assignment};
use crate::similarity::Similarity;

/// One frame of a sequence: the ground-truth objects and the tracker's hypotheses, each with
/// its id. Ids must be unique within a frame (per side); a frame may be empty on either side.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame<T> {
    /// Ground-truth objects `(id, value)`.
    pub gt: Vec<(i64, T)>,
    /// Tracker hypotheses `(id, value)`.
    pub hyp: Vec<(i64, T)>,
}

impl<T> Default for Frame<T> {
    fn default() -> Self {
        Self {
            gt: Vec::new(),
            hyp: Vec::new(),
        }
    }
}

/// One frame after comparison: compact id indices and the pairwise matrices (row = gt).
#[derive(Debug, Clone)]
struct PreparedFrame {
    gt: Vec<usize>,
    hyp: Vec<usize>,
    /// py-motmetrics distances, NaN = may not pair.
    dist: Vec<f64>,
    /// TrackEval similarities in [0, 1].
    sim: Vec<f64>,
}

/// A sequence compared once with a [`Similarity`], ready for every metric.
///
/// Building it computes the pairwise distance and similarity matrices of each frame, so
/// scoring CLEAR MOT, IDF1 and HOTA from one `MotEvaluation` compares each pair only once.
#[derive(Debug, Clone)]
pub struct MotEvaluation {
    frames: Vec<PreparedFrame>,
    gt_ids: Vec<i64>,
    hyp_ids: Vec<i64>,
}

fn compact(ids: impl Iterator<Item = i64>) -> (Vec<i64>, HashMap<i64, usize>) {
    let mut v: Vec<i64> = ids.collect();
    v.sort_unstable();
    v.dedup();
    let map = v.iter().enumerate().map(|(i, &id)| (id, i)).collect();
    (v, map)
}

impl MotEvaluation {
    /// Compares every ground-truth object with every hypothesis of the same frame.
    ///
    /// Errors: a duplicate id within a frame, or a non-finite distance or similarity (NaN
    /// coordinates in the input).
    pub fn new<T, S: Similarity<T> + ?Sized>(
        frames: &[Frame<T>],
        similarity: &S,
    ) -> Result<Self, EvalError> {
        let (gt_ids, gt_map) = compact(frames.iter().flat_map(|f| f.gt.iter().map(|p| p.0)));
        let (hyp_ids, hyp_map) = compact(frames.iter().flat_map(|f| f.hyp.iter().map(|p| p.0)));
        let mut out = Vec::with_capacity(frames.len());
        let mut seen = HashSet::new();
        for (k, f) in frames.iter().enumerate() {
            seen.clear();
            for &(id, _) in &f.gt {
                if !seen.insert(id) {
                    return Err(EvalError::DuplicateId {
                        which: "ground truth",
                        frame: k as u64,
                        id,
                    });
                }
            }
            seen.clear();
            for &(id, _) in &f.hyp {
                if !seen.insert(id) {
                    return Err(EvalError::DuplicateId {
                        which: "hypothesis",
                        frame: k as u64,
                        id,
                    });
                }
            }
            let n = f.gt.len() * f.hyp.len();
            let mut dist = Vec::with_capacity(n);
            let mut sim = Vec::with_capacity(n);
            for (_, g) in &f.gt {
                for (_, h) in &f.hyp {
                    let d = similarity.distance(g, h);
                    let s = similarity.similarity(g, h);
                    if d.is_some_and(|d| !d.is_finite()) || !s.is_finite() {
                        return Err(CoreError::NonFinite {
                            what: "object coordinates (distance or similarity)",
                        }
                        .into());
                    }
                    dist.push(d.unwrap_or(f64::NAN));
                    sim.push(s);
                }
            }
            out.push(PreparedFrame {
                gt: f.gt.iter().map(|p| gt_map[&p.0]).collect(),
                hyp: f.hyp.iter().map(|p| hyp_map[&p.0]).collect(),
                dist,
                sim,
            });
        }
        Ok(Self {
            frames: out,
            gt_ids,
            hyp_ids,
        })
    }

    /// The distinct ground-truth ids, sorted.
    pub fn gt_ids(&self) -> &[i64] {
        &self.gt_ids
    }

    /// The distinct hypothesis ids, sorted.
    pub fn hyp_ids(&self) -> &[i64] {
        &self.hyp_ids
    }

    /// Number of frames.
    pub fn num_frames(&self) -> usize {
        self.frames.len()
    }

    /// CLEAR MOT with py-motmetrics' conventions (see the module docs).
    pub fn clear_mot(&self) -> Result<ClearMot, EvalError> {
        clear_mot_prepared(self, None)
    }

    /// The correspondences CLEAR MOT settles on, per frame: `(ground-truth id, hypothesis id)`
    /// for every matched pair (carried-forward and newly assigned alike), in the order of the
    /// frames given to [`MotEvaluation::new`]. For checks such as "the track that carried
    /// object A before an occlusion carries it again after".
    pub fn clear_matches(&self) -> Result<Vec<Vec<(i64, i64)>>, EvalError> {
        let mut out = Vec::with_capacity(self.frames.len());
        clear_mot_prepared(self, Some(&mut out))?;
        Ok(out)
    }

    /// The identity measures IDF1, IDP, IDR.
    pub fn identity(&self) -> Result<Identity, EvalError> {
        identity_prepared(self)
    }

    /// HOTA per TrackEval.
    pub fn hota(&self) -> Result<Hota, EvalError> {
        hota_prepared(self)
    }

    /// All three families.
    pub fn summary(&self) -> Result<MotSummary, EvalError> {
        Ok(MotSummary {
            clear: self.clear_mot()?,
            identity: self.identity()?,
            hota: self.hota()?,
        })
    }
}

/// `a / b`, `None` when `b == 0` (py-motmetrics' `quiet_divide` would give NaN).
fn ratio(a: f64, b: f64) -> Option<f64> {
    (b != 0.0).then(|| a / b)
}

/// CLEAR MOT counts and ratios (Bernardin & Stiefelhagen 2008), py-motmetrics conventions.
///
/// Field names follow py-motmetrics' metric names.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct ClearMot {
    /// Frames in the sequence.
    pub num_frames: usize,
    /// Ground-truth object occurrences (the MOTA denominator).
    pub num_objects: usize,
    /// Hypothesis occurrences.
    pub num_predictions: usize,
    /// Distinct ground-truth ids.
    pub num_unique_objects: usize,
    /// Matches that are not switches (py-motmetrics `MATCH` events).
    pub num_matches: usize,
    /// Identity switches (`SWITCH` events).
    pub num_switches: usize,
    /// Matched pairs, switches included (`num_matches + num_switches`).
    pub num_detections: usize,
    /// Unmatched hypotheses.
    pub num_false_positives: usize,
    /// Unmatched ground-truth occurrences.
    pub num_misses: usize,
    /// Switches from tracked to missed within an object's tracked span.
    pub num_fragmentations: usize,
    /// Hypotheses that moved from one object to another (`TRANSFER`).
    pub num_transfer: usize,
    /// Switches to a hypothesis never matched before (`ASCEND`).
    pub num_ascend: usize,
    /// Transfers to an object never matched before (`MIGRATE`).
    pub num_migrate: usize,
    /// Objects tracked in at least 80 % of their occurrences.
    pub mostly_tracked: usize,
    /// Objects tracked in 20 % to 80 % of their occurrences.
    pub partially_tracked: usize,
    /// Objects tracked in less than 20 % of their occurrences.
    pub mostly_lost: usize,
    /// Sum of the distances of matched pairs.
    pub distance_sum: f64,
}

impl ClearMot {
    /// `1 - (FN + FP + IDSW) / GT`; `None` without ground truth.
    pub fn mota(&self) -> Option<f64> {
        ratio(
            (self.num_misses + self.num_switches + self.num_false_positives) as f64,
            self.num_objects as f64,
        )
        .map(|r| 1.0 - r)
    }

    /// `1 - (FN + FP) / GT`; `None` without ground truth.
    pub fn moda(&self) -> Option<f64> {
        ratio(
            (self.num_misses + self.num_false_positives) as f64,
            self.num_objects as f64,
        )
        .map(|r| 1.0 - r)
    }

    /// py-motmetrics' MOTP: the mean **distance** of matched pairs (`1 - IoU` for boxes, so
    /// lower is better; metres for [`crate::similarity::Euclidean`]). `None` without matches.
    pub fn motp(&self) -> Option<f64> {
        ratio(self.distance_sum, self.num_detections as f64)
    }

    /// MOTChallenge's MOTP for box distances: the mean IoU of matched pairs in percent,
    /// `100 (1 - motp())`. Only meaningful when the distance is `1 - IoU`.
    pub fn motchallenge_motp(&self) -> Option<f64> {
        self.motp().map(|d| 100.0 * (1.0 - d))
    }

    /// Matched / ground-truth occurrences.
    pub fn recall(&self) -> Option<f64> {
        ratio(self.num_detections as f64, self.num_objects as f64)
    }

    /// Matched / hypothesis occurrences.
    pub fn precision(&self) -> Option<f64> {
        ratio(
            self.num_detections as f64,
            (self.num_detections + self.num_false_positives) as f64,
        )
    }
}

/// CLEAR MOT of a sequence (py-motmetrics conventions; see the module docs).
pub fn clear_mot<T, S: Similarity<T> + ?Sized>(
    frames: &[Frame<T>],
    similarity: &S,
) -> Result<ClearMot, EvalError> {
    MotEvaluation::new(frames, similarity)?.clear_mot()
}

fn clear_mot_prepared(
    ev: &MotEvaluation,
    mut matches: Option<&mut Vec<Vec<(i64, i64)>>>,
) -> Result<ClearMot, EvalError> {
    let n_gt = ev.gt_ids.len();
    let n_hyp = ev.hyp_ids.len();
    // py-motmetrics accumulator state
    let mut m: Vec<Option<usize>> = vec![None; n_gt]; // object -> last matched hypothesis
    let mut res_m: Vec<Option<usize>> = vec![None; n_hyp]; // hypothesis -> last object (step 2 only)
    let mut last_match = vec![false; n_gt];
    let mut hyp_history = vec![false; n_hyp];
    // per-object state sequence for Frag / MT / ML
    let mut tracked_states: Vec<Vec<bool>> = vec![Vec::new(); n_gt];

    let mut c = ClearMot {
        num_frames: ev.frames.len(),
        num_objects: 0,
        num_predictions: 0,
        num_unique_objects: n_gt,
        num_matches: 0,
        num_switches: 0,
        num_detections: 0,
        num_false_positives: 0,
        num_misses: 0,
        num_fragmentations: 0,
        num_transfer: 0,
        num_ascend: 0,
        num_migrate: 0,
        mostly_tracked: 0,
        partially_tracked: 0,
        mostly_lost: 0,
        distance_sum: 0.0,
    };

    let mut dists: Vec<f64> = Vec::new();
    for f in &ev.frames {
        let no = f.gt.len();
        let nh = f.hyp.len();
        c.num_objects += no;
        c.num_predictions += nh;
        let mut o_masked = vec![false; no];
        let mut h_masked = vec![false; nh];
        if no > 0 && nh > 0 {
            dists.clear();
            dists.extend_from_slice(&f.dist);
            // 1. carry forward established correspondences
            for i in 0..no {
                let o = f.gt[i];
                let Some(hprev) = m[o] else { continue };
                let Some(j) = (0..nh).find(|&j| !h_masked[j] && f.hyp[j] == hprev) else {
                    continue;
                };
                let d = dists[i * nh + j];
                if d.is_finite() {
                    o_masked[i] = true;
                    h_masked[j] = true;
                    c.num_matches += 1;
                    c.distance_sum += d;
                    last_match[o] = true;
                    hyp_history[hprev] = true;
                }
            }
            // 2. optimal assignment of the rest
            for i in 0..no {
                for j in 0..nh {
                    if o_masked[i] || h_masked[j] {
                        dists[i * nh + j] = f64::NAN;
                    }
                }
            }
            for (i, j) in assign_with_forbidden(&dists, no, nh)? {
                let d = dists[i * nh + j];
                let o = f.gt[i];
                let h = f.hyp[j];
                let is_switch = m[o].is_some_and(|prev| prev != h);
                if is_switch {
                    c.num_switches += 1;
                    if !hyp_history[h] {
                        c.num_ascend += 1;
                    }
                } else {
                    c.num_matches += 1;
                }
                if res_m[h].is_some_and(|prev| prev != o) {
                    c.num_transfer += 1;
                    if !last_match[o] {
                        c.num_migrate += 1;
                    }
                }
                c.distance_sum += d;
                hyp_history[h] = true;
                last_match[o] = true;
                o_masked[i] = true;
                h_masked[j] = true;
                m[o] = Some(h);
                res_m[h] = Some(o);
            }
        }
        if let Some(out) = matches.as_deref_mut() {
            out.push(
                (0..no)
                    .filter_map(|i| {
                        let o = f.gt[i];
                        let h = m[o]?;
                        (o_masked[i] && f.hyp.contains(&h)).then(|| (ev.gt_ids[o], ev.hyp_ids[h]))
                    })
                    .collect(),
            );
        }
        for i in 0..no {
            tracked_states[f.gt[i]].push(o_masked[i]);
            if !o_masked[i] {
                c.num_misses += 1;
            }
        }
        c.num_false_positives += h_masked.iter().filter(|&&x| !x).count();
    }
    c.num_detections = c.num_matches + c.num_switches;

    for states in &tracked_states {
        let tracked = states.iter().filter(|&&s| s).count();
        if let (Some(first), Some(last)) = (
            states.iter().position(|&s| s),
            states.iter().rposition(|&s| s),
        ) {
            c.num_fragmentations += (first + 1..=last)
                .filter(|&k| !states[k] && states[k - 1])
                .count();
        }
        if states.is_empty() {
            continue;
        }
        let r = tracked as f64 / states.len() as f64;
        if r >= 0.8 {
            c.mostly_tracked += 1;
        } else if r >= 0.2 {
            c.partially_tracked += 1;
        } else {
            c.mostly_lost += 1;
        }
    }
    Ok(c)
}

/// The identity measures (Ristani et al. 2016).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Identity {
    /// Frames in which an object is matched to the trajectory globally assigned to it.
    pub idtp: usize,
    /// Hypothesis occurrences not covered by the global assignment.
    pub idfp: usize,
    /// Ground-truth occurrences not covered by the global assignment.
    pub idfn: usize,
}

impl Identity {
    /// `2 IDTP / (2 IDTP + IDFP + IDFN)`; `None` when both sides are empty.
    pub fn idf1(&self) -> Option<f64> {
        ratio(
            2.0 * self.idtp as f64,
            (2 * self.idtp + self.idfp + self.idfn) as f64,
        )
    }
    /// ID precision `IDTP / (IDTP + IDFP)`.
    pub fn idp(&self) -> Option<f64> {
        ratio(self.idtp as f64, (self.idtp + self.idfp) as f64)
    }
    /// ID recall `IDTP / (IDTP + IDFN)`.
    pub fn idr(&self) -> Option<f64> {
        ratio(self.idtp as f64, (self.idtp + self.idfn) as f64)
    }
}

/// The identity measures IDF1 / IDP / IDR of a sequence: a frame counts for a pair when its
/// [`Similarity::distance`] is within the threshold.
pub fn idf1<T, S: Similarity<T> + ?Sized>(
    frames: &[Frame<T>],
    similarity: &S,
) -> Result<Identity, EvalError> {
    MotEvaluation::new(frames, similarity)?.identity()
}

fn identity_prepared(ev: &MotEvaluation) -> Result<Identity, EvalError> {
    let n_gt = ev.gt_ids.len();
    let n_hyp = ev.hyp_ids.len();
    let mut tps = vec![0.0_f64; n_gt * n_hyp];
    let mut total_gt = 0usize;
    let mut total_hyp = 0usize;
    for f in &ev.frames {
        total_gt += f.gt.len();
        total_hyp += f.hyp.len();
        let nh = f.hyp.len();
        for (i, &o) in f.gt.iter().enumerate() {
            for (j, &h) in f.hyp.iter().enumerate() {
                if f.dist[i * nh + j].is_finite() {
                    tps[o * n_hyp + h] += 1.0;
                }
            }
        }
    }
    // Maximising the matched frame count is the same problem as the (n_gt + n_hyp)^2 min-cost
    // formulation of the reference tools (cost = IDFN + IDFP = GT + HYP - 2 IDTP), and its optimal
    // value is unique, so the smaller rectangular problem gives the same numbers.
    let neg: Vec<f64> = tps.iter().map(|&x| -x).collect();
    let idtp: f64 = linear_sum_assignment(&neg, n_gt, n_hyp)?
        .into_iter()
        .map(|(i, j)| tps[i * n_hyp + j])
        .sum();
    let idtp = idtp.round() as usize;
    Ok(Identity {
        idtp,
        idfp: total_hyp - idtp,
        idfn: total_gt - idtp,
    })
}

/// The alpha thresholds of HOTA: `0.05 + 0.05 k`, k = 0..19 (numpy's `arange(0.05, 0.99, 0.05)`,
/// bit for bit).
pub fn hota_alphas() -> [f64; 19] {
    std::array::from_fn(|k| 0.05 + k as f64 * 0.05)
}

/// HOTA and its sub-metrics (Luiten et al. 2021), TrackEval conventions. Each array holds one
/// value per alpha of [`hota_alphas`]; the scalar accessors average over alpha.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Hota {
    /// Higher-order tracking accuracy `sqrt(DetA AssA)` per alpha.
    pub hota: [f64; 19],
    /// Detection accuracy `TP / (TP + FN + FP)` per alpha.
    pub deta: [f64; 19],
    /// Association accuracy per alpha.
    pub assa: [f64; 19],
    /// Detection recall per alpha.
    pub detre: [f64; 19],
    /// Detection precision per alpha.
    pub detpr: [f64; 19],
    /// Association recall per alpha.
    pub assre: [f64; 19],
    /// Association precision per alpha.
    pub asspr: [f64; 19],
    /// Localisation accuracy (mean similarity of matches) per alpha.
    pub loca: [f64; 19],
    /// True positives per alpha.
    pub tp: [usize; 19],
    /// False negatives per alpha.
    pub fn_: [usize; 19],
    /// False positives per alpha.
    pub fp: [usize; 19],
}

fn mean19(a: &[f64; 19]) -> f64 {
    a.iter().sum::<f64>() / 19.0
}

impl Hota {
    /// HOTA averaged over alpha.
    pub fn hota_mean(&self) -> f64 {
        mean19(&self.hota)
    }
    /// DetA averaged over alpha.
    pub fn deta_mean(&self) -> f64 {
        mean19(&self.deta)
    }
    /// AssA averaged over alpha.
    pub fn assa_mean(&self) -> f64 {
        mean19(&self.assa)
    }
    /// LocA averaged over alpha.
    pub fn loca_mean(&self) -> f64 {
        mean19(&self.loca)
    }
    /// DetRe averaged over alpha.
    pub fn detre_mean(&self) -> f64 {
        mean19(&self.detre)
    }
    /// DetPr averaged over alpha.
    pub fn detpr_mean(&self) -> f64 {
        mean19(&self.detpr)
    }
    /// AssRe averaged over alpha.
    pub fn assre_mean(&self) -> f64 {
        mean19(&self.assre)
    }
    /// AssPr averaged over alpha.
    pub fn asspr_mean(&self) -> f64 {
        mean19(&self.asspr)
    }
}

/// HOTA of a sequence, per TrackEval (see the module docs).
pub fn hota<T, S: Similarity<T> + ?Sized>(
    frames: &[Frame<T>],
    similarity: &S,
) -> Result<Hota, EvalError> {
    MotEvaluation::new(frames, similarity)?.hota()
}

fn hota_prepared(ev: &MotEvaluation) -> Result<Hota, EvalError> {
    const EPS: f64 = f64::EPSILON;
    let alphas = hota_alphas();
    let mut tp = [0usize; 19];
    let mut fn_ = [0usize; 19];
    let mut fp = [0usize; 19];
    let mut loca = [0.0f64; 19];
    let zeros = [0.0f64; 19];
    let num_gt_dets: usize = ev.frames.iter().map(|f| f.gt.len()).sum();
    let num_hyp_dets: usize = ev.frames.iter().map(|f| f.hyp.len()).sum();
    if num_hyp_dets == 0 {
        return Ok(finish_hota(
            tp,
            [num_gt_dets; 19],
            fp,
            [1.0; 19],
            zeros,
            zeros,
            zeros,
        ));
    }
    if num_gt_dets == 0 {
        return Ok(finish_hota(
            tp,
            fn_,
            [num_hyp_dets; 19],
            [1.0; 19],
            zeros,
            zeros,
            zeros,
        ));
    }

    let n_gt = ev.gt_ids.len();
    let n_hyp = ev.hyp_ids.len();
    let mut potential = vec![0.0f64; n_gt * n_hyp];
    let mut gt_count = vec![0.0f64; n_gt];
    let mut hyp_count = vec![0.0f64; n_hyp];
    for f in &ev.frames {
        let (no, nh) = (f.gt.len(), f.hyp.len());
        let row_sum: Vec<f64> = (0..no)
            .map(|i| f.sim[i * nh..(i + 1) * nh].iter().sum())
            .collect();
        let col_sum: Vec<f64> = (0..nh)
            .map(|j| (0..no).map(|i| f.sim[i * nh + j]).sum())
            .collect();
        for i in 0..no {
            for j in 0..nh {
                let s = f.sim[i * nh + j];
                let denom = col_sum[j] + row_sum[i] - s;
                if denom > EPS {
                    potential[f.gt[i] * n_hyp + f.hyp[j]] += s / denom;
                }
            }
        }
        for &o in &f.gt {
            gt_count[o] += 1.0;
        }
        for &h in &f.hyp {
            hyp_count[h] += 1.0;
        }
    }
    let global: Vec<f64> = (0..n_gt * n_hyp)
        .map(|k| {
            let (o, h) = (k / n_hyp, k % n_hyp);
            potential[k] / (gt_count[o] + hyp_count[h] - potential[k])
        })
        .collect();

    // matched-pair counts per alpha, sparse (most id pairs never match)
    let mut matches: std::collections::BTreeMap<usize, [f64; 19]> =
        std::collections::BTreeMap::new();
    let mut score = Vec::new();
    for f in &ev.frames {
        let (no, nh) = (f.gt.len(), f.hyp.len());
        if no == 0 {
            for x in &mut fp {
                *x += nh;
            }
            continue;
        }
        if nh == 0 {
            for x in &mut fn_ {
                *x += no;
            }
            continue;
        }
        score.clear();
        for i in 0..no {
            for j in 0..nh {
                score.push(-(global[f.gt[i] * n_hyp + f.hyp[j]] * f.sim[i * nh + j]));
            }
        }
        let pairs = linear_sum_assignment(&score, no, nh)?;
        for (a, &alpha) in alphas.iter().enumerate() {
            let mut n = 0;
            for &(i, j) in &pairs {
                let s = f.sim[i * nh + j];
                if s >= alpha - EPS {
                    n += 1;
                    loca[a] += s;
                    matches
                        .entry(f.gt[i] * n_hyp + f.hyp[j])
                        .or_insert([0.0; 19])[a] += 1.0;
                }
            }
            tp[a] += n;
            fn_[a] += no - n;
            fp[a] += nh - n;
        }
    }
    let mut assa = zeros;
    let mut assre = zeros;
    let mut asspr = zeros;
    for a in 0..19 {
        let mut sa = 0.0;
        let mut sr = 0.0;
        let mut sp = 0.0;
        for (&k, counts) in &matches {
            let mc = counts[a];
            if mc == 0.0 {
                continue;
            }
            let (o, h) = (k / n_hyp, k % n_hyp);
            sa += mc * (mc / (gt_count[o] + hyp_count[h] - mc).max(1.0));
            sr += mc * (mc / gt_count[o].max(1.0));
            sp += mc * (mc / hyp_count[h].max(1.0));
        }
        let den = (tp[a] as f64).max(1.0);
        assa[a] = sa / den;
        assre[a] = sr / den;
        asspr[a] = sp / den;
        loca[a] = loca[a].max(1e-10) / (tp[a] as f64).max(1e-10);
    }
    Ok(finish_hota(tp, fn_, fp, loca, assa, assre, asspr))
}

/// TrackEval's `_compute_final_fields`.
fn finish_hota(
    tp: [usize; 19],
    fn_: [usize; 19],
    fp: [usize; 19],
    loca: [f64; 19],
    assa: [f64; 19],
    assre: [f64; 19],
    asspr: [f64; 19],
) -> Hota {
    let deta: [f64; 19] =
        std::array::from_fn(|a| tp[a] as f64 / ((tp[a] + fn_[a] + fp[a]) as f64).max(1.0));
    let detre: [f64; 19] =
        std::array::from_fn(|a| tp[a] as f64 / ((tp[a] + fn_[a]) as f64).max(1.0));
    let detpr: [f64; 19] =
        std::array::from_fn(|a| tp[a] as f64 / ((tp[a] + fp[a]) as f64).max(1.0));
    let hota = std::array::from_fn(|a| (deta[a] * assa[a]).sqrt());
    Hota {
        hota,
        deta,
        assa,
        detre,
        detpr,
        assre,
        asspr,
        loca,
        tp,
        fn_,
        fp,
    }
}

/// CLEAR MOT, identity and HOTA of one sequence.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct MotSummary {
    /// CLEAR MOT (py-motmetrics conventions).
    pub clear: ClearMot,
    /// IDF1 / IDP / IDR.
    pub identity: Identity,
    /// HOTA (TrackEval conventions).
    pub hota: Hota,
}

/// CLEAR MOT, identity and HOTA of a sequence in one call (each pair compared once).
pub fn evaluate<T, S: Similarity<T> + ?Sized>(
    frames: &[Frame<T>],
    similarity: &S,
) -> Result<MotSummary, EvalError> {
    MotEvaluation::new(frames, similarity)?.summary()
}

#[cfg(test)]
mod match_tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::Euclidean;

    /// The matches carry an established pair forward even when another hypothesis is nearer,
    /// and count as a switch only when the pair breaks.
    #[test]
    fn clear_matches_follow_the_carry_forward_rule() {
        let f = |gt: Vec<(i64, [f64; 2])>, hyp: Vec<(i64, [f64; 2])>| Frame { gt, hyp };
        let frames = vec![
            f(vec![(1, [0.0, 0.0])], vec![(10, [0.3, 0.0])]),
            // 11 is nearer, but 10 is still within the threshold: 10 keeps the object
            f(
                vec![(1, [0.0, 0.0])],
                vec![(10, [0.4, 0.0]), (11, [0.0, 0.0])],
            ),
            // 10 leaves the threshold: 11 takes over (a switch)
            f(
                vec![(1, [0.0, 0.0])],
                vec![(10, [2.0, 0.0]), (11, [0.0, 0.0])],
            ),
            f(vec![(1, [0.0, 0.0])], vec![]),
        ];
        let ev = MotEvaluation::new(&frames, &Euclidean::new(0.5).unwrap()).unwrap();
        let m = ev.clear_matches().unwrap();
        assert_eq!(m, vec![vec![(1, 10)], vec![(1, 10)], vec![(1, 11)], vec![]]);
        let c = ev.clear_mot().unwrap();
        assert_eq!((c.num_switches, c.num_misses), (1, 1));
    }
}
