//! The occlusion state of the target (spec §2.8 step 7) and what it allows: which state a frame
//! is in after the selection, and whether the template may learn from the selected candidate
//! (eq. 12 runs only while the target is seen whole).

use quarry_vision::multicue::CandidateScore;
use serde::{Deserialize, Serialize};

use super::RgbdPersonConfig;
use super::select::{DetectionTier, Selection};

/// The occlusion state of the target (spec §2.8 step 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum OcclusionState {
    /// T1 without the depth flag.
    Normal,
    /// T2a / T2b without the depth flag (one cue failed).
    AppearanceChange,
    /// Detection with the depth flag, or T3 with `m ≥ 0.5`.
    PartialOcclusion,
    /// T3 with `m < 0.5`.
    SevereOcclusion,
    /// No detection: the MEKF prediction is the output.
    FullOcclusion,
    /// More than `lost_after` frames of full occlusion.
    Lost,
}

impl OcclusionState {
    /// `Normal` or `AppearanceChange`: the target is seen whole, so the template may learn and
    /// the box size may follow the target depth.
    #[must_use]
    pub fn is_unoccluded(self) -> bool {
        matches!(self, Self::Normal | Self::AppearanceChange)
    }
}

/// The state of a frame with a detection: `sel` is the selection, `full` the selected
/// candidate's score over all its patches.
pub(super) fn detected(
    cfg: &RgbdPersonConfig,
    sel: &Selection,
    full: &CandidateScore,
) -> OcclusionState {
    if cfg.baseline {
        OcclusionState::Normal
    } else if sel.t3 {
        if full.m >= cfg.severe_fraction {
            OcclusionState::PartialOcclusion
        } else {
            OcclusionState::SevereOcclusion
        }
    } else if full.d_flag {
        OcclusionState::PartialOcclusion
    } else if sel.tier == DetectionTier::Overall {
        OcclusionState::Normal
    } else {
        OcclusionState::AppearanceChange
    }
}

/// The state of the `full_count`-th consecutive frame without a detection.
pub(super) fn undetected(full_count: u32, lost_after: u32) -> OcclusionState {
    if full_count > lost_after {
        OcclusionState::Lost
    } else {
        OcclusionState::FullOcclusion
    }
}

/// Whether the template learns from the selected candidate (score `full` over all patches;
/// `valid` = the template's valid patches) in `state`: only when the target is seen whole
/// (and, with `learn_unoccluded_only`, every valid patch is unoccluded), unless the occlusion
/// gate is off; with `update_fraction` also only when `m(c*)` reaches it.
pub(super) fn may_learn(
    cfg: &RgbdPersonConfig,
    state: OcclusionState,
    valid: &[bool],
    full: &CandidateScore,
) -> bool {
    let all_seen =
        !cfg.learn_unoccluded_only || valid.iter().zip(&full.unoccluded).all(|(&v, &u)| !v || u);
    let learnable = (state.is_unoccluded() && all_seen) || !cfg.occlusion_gate;
    let frac_ok = cfg.update_fraction.is_none_or(|u| full.m >= u);
    learnable && frac_ok
}
