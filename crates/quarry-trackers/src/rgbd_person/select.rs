//! Tiered selection of the target among the scored candidates (spec §2.8 steps 5-6): T1 on the
//! overall score with `m ≥ a`, else T2a on colour only, else T2b on texture only (with the
//! self-score guard), else T3: the same three tiers over the unoccluded patches of the
//! candidates that show an occluder. The whole-target baseline takes the argmax of `S` instead.
//! Ties go to the candidate nearest the projected MEKF prediction, then to the lower index.

use quarry_core::BBox;
use quarry_vision::multicue::{CandidateScore, PatchDescriptor, PatchMultiCueModel};
use serde::{Deserialize, Serialize};

use super::RgbdPersonConfig;

/// Which tier selected the target.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum DetectionTier {
    /// T1: overall score, `m ≥ a`.
    Overall,
    /// T2a: colour only.
    ColourOnly,
    /// T2b: texture only.
    TextureOnly,
    /// T3: the same rule over the unoccluded patches.
    Unoccluded(Box<DetectionTier>),
}

/// The selected candidate.
#[derive(Debug, Clone)]
pub(super) struct Selection {
    /// Index into the candidates.
    pub index: usize,
    /// The selecting tier.
    pub tier: DetectionTier,
    /// The selecting score (for T3: over the candidate's unoccluded patches).
    pub score: CandidateScore,
    /// Selected by T3.
    pub t3: bool,
}

/// The target among `cands` (described and scored in `described`, same order), or `None` when
/// no tier accepts a candidate. `pred` is the projected MEKF prediction (for the ties).
pub(super) fn select(
    cfg: &RgbdPersonConfig,
    model: &PatchMultiCueModel,
    cands: &[BBox],
    described: &[(PatchDescriptor, CandidateScore)],
    pred: Option<(f64, f64)>,
) -> Option<Selection> {
    let k_min = model.k_min();
    let n_valid = model.valid().iter().filter(|&&v| v).count();
    let a = cfg.accept_fraction;
    let dist = |b: &BBox| pred.map_or(0.0, |(u, v)| (b.cx - u).hypot(b.cy - v));
    // argmax with ties: score, then distance to the MEKF candidate, then index
    let pick = |items: &[(usize, f32)]| -> Option<usize> {
        let mut best: Option<(usize, f32, f64)> = None;
        for &(i, sc) in items {
            let d = dist(&cands[i]);
            let better = match best {
                None => true,
                Some((_, bs, bd)) => sc > bs || (sc == bs && d < bd),
            };
            if better {
                best = Some((i, sc, d));
            }
        }
        best.map(|b| b.0)
    };
    let t2b_min = |n_scored: usize| {
        cfg.t2b_self_score_fraction
            .map_or(f32::NEG_INFINITY, |f| f * model.cue_self_score(n_scored))
    };
    let tiers = |sc: &dyn Fn(usize) -> Option<(CandidateScore, usize)>,
                 pool: &[usize],
                 need: usize|
     -> Option<(usize, DetectionTier, CandidateScore)> {
        let scored: Vec<(usize, CandidateScore, usize)> = pool
            .iter()
            .filter_map(|&i| sc(i).map(|(s, n)| (i, s, n)))
            .collect();
        let t1: Vec<(usize, f32)> = scored
            .iter()
            .filter(|(_, s, _)| s.m >= a && s.n_pass >= need)
            .map(|(i, s, _)| (*i, s.s))
            .collect();
        if let Some(i) = pick(&t1) {
            let s = scored.iter().find(|x| x.0 == i).map(|x| x.1.clone())?;
            return Some((i, DetectionTier::Overall, s));
        }
        let t2a: Vec<(usize, f32)> = scored
            .iter()
            .filter(|(_, s, _)| s.m_cd >= a && s.n_pass_cd >= need)
            .map(|(i, s, _)| (*i, s.s_cd))
            .collect();
        if let Some(i) = pick(&t2a) {
            let s = scored.iter().find(|x| x.0 == i).map(|x| x.1.clone())?;
            return Some((i, DetectionTier::ColourOnly, s));
        }
        let t2b: Vec<(usize, f32)> = scored
            .iter()
            .filter(|(_, s, n)| s.m_ld >= a && s.n_pass_ld >= need && s.s_ld >= t2b_min(*n))
            .map(|(i, s, _)| (*i, s.s_ld))
            .collect();
        pick(&t2b).and_then(|i| {
            let s = scored.iter().find(|x| x.0 == i).map(|x| x.1.clone())?;
            Some((i, DetectionTier::TextureOnly, s))
        })
    };
    let selection = |(index, tier, score), t3| Selection {
        index,
        tier,
        score,
        t3,
    };
    if cfg.baseline {
        let items: Vec<(usize, f32)> = described
            .iter()
            .enumerate()
            .map(|(i, x)| (i, x.1.s))
            .collect();
        return pick(&items)
            .map(|i| selection((i, DetectionTier::Overall, described[i].1.clone()), false));
    }
    let all: Vec<usize> = (0..cands.len()).collect();
    if let Some(t) = tiers(&|i| Some((described[i].1.clone(), n_valid)), &all, 0) {
        return Some(selection(t, false));
    }
    let t3_pool: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| {
            let (d, s) = &described[i];
            (s.d_flag || d.out_of_view) && s.unoccluded.iter().filter(|&&u| u).count() >= k_min
        })
        .collect();
    let sub = |i: usize| {
        let (d, s) = &described[i];
        let n = s.unoccluded.iter().filter(|&&u| u).count();
        Some((model.score_over(d, &s.unoccluded), n))
    };
    tiers(&sub, &t3_pool, k_min)
        .map(|(i, t, s)| selection((i, DetectionTier::Unoccluded(Box::new(t)), s), true))
}
