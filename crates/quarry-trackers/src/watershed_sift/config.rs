//! [`WatershedSiftConfig`]: every parameter of spec 004 §3, serde/TOML, `Default` = `paper`.
//!
//! Tags on each field: **\[paper\]** stated in the paper (spec §3.1), **\[spec\]** a gap the spec
//! resolved (§3.2, §6), **\[ext\]** an extension that is off in `paper` and on in `robust`
//! (spec §3.2 last paragraph), **\[ours\]** a choice of this implementation, with its reason.

use crate::TrackerError;
use quarry_vision::{MedianBackgroundParams, MotionTest, PoolParams};
use serde::{Deserialize, Serialize};

/// The two profiles of spec 004.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Profile {
    /// The paper with the spec's resolutions, every extension off (default).
    #[default]
    Paper,
    /// The paper plus the documented extensions: coherent grouping, offset voting, n_min = 3,
    /// the region gate, and the real-video fixes of docs/video-tracker.md.
    Robust,
}

impl crate::PresetName for Profile {
    const ALL: &'static [Self] = &[Self::Paper, Self::Robust];
    const TRACKER: &'static str = "watershed_sift";

    fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Robust => "robust",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::Paper => "the paper with the spec's gap fills, no extension (default)",
            Self::Robust => "the paper plus the spec's extensions and the real-video fixes",
        }
    }
}

/// Which grey level a person is assumed to have against the ground (spec §2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Polarity {
    /// People darker than the background: segment `I` (the paper's assumption).
    #[default]
    Dark,
    /// People brighter: segment `255 - I` \[ext\].
    Bright,
}

/// Largest accepted blur σ, pixels (the blur refuses wider kernels anyway).
pub const MAX_SIGMA: f64 = 64.0;
/// Largest accepted box side, pixels.
pub const MAX_BOX_SIDE: f64 = 4096.0;
/// Largest trajectory length N.
pub const MAX_N: usize = 1000;
/// Largest frame count of the termination rules.
pub const MAX_FRAMES_RULE: usize = 100_000;

/// Every parameter of spec 004 §3.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WatershedSiftConfig {
    /// Which profile the values below came from (informational; the values rule).
    pub preset: Profile,

    // ----- segmentation (§2.2-2.5) -----
    /// Gaussian σ before the watershed, pixels [paper: 8.0 for 30-px-wide people; set per
    /// sequence as ≈ 0.27·`box_w`, §5.4 — see [`WatershedSiftConfig::with_person_size`]].
    pub sigma: f64,
    /// Grey levels L of eq. (2) [paper: 256].
    pub levels: u32,
    /// Person polarity [paper: dark; `bright` is an ext].
    pub polarity: Polarity,

    // ----- target box (§2.9) -----
    /// Box width w, pixels: the ROI and the reported box [paper: 30; per sequence, the typical
    /// person width, §5.4, never from ground truth].
    pub box_w: f64,
    /// Box height h, pixels [paper: 80; per sequence, the typical person height].
    pub box_h: f64,

    // ----- moving points (§2.8) -----
    /// Trajectory length N, frames [paper: 10].
    pub n: usize,
    /// Displacement threshold M_Thred of eq. (6), pixels (L1) [paper: 0].
    pub m_thred: f64,
    /// Variance threshold V_Thred of eq. (7) [paper: 0.01].
    pub v_thred: f64,

    // ----- SIFT pools (§2.10-2.12) -----
    /// D_Thred of eq. (9), L2 on u8 descriptors of norm ≈ 512 [paper: 150; scale spec A5].
    pub d_thred: f32,
    /// ρ of the ratio test [paper: 0.5].
    pub ratio: f32,
    /// ρ on squared distances [spec A5: false].
    pub ratio_on_squared: bool,
    /// W_del, pool deletion threshold [paper: -7].
    pub w_del: f64,
    /// Pool safety cap [spec: 1000].
    pub pool_cap: usize,
    /// τ_split, split-region ownership ratio [paper: 0.48].
    pub tau_split: f64,
    /// n_min, fewest keypoints for the ownership test [spec: 1; `robust`: 3].
    pub n_min: usize,
    /// SIFT crop padding around an area, pixels [spec: 24].
    pub sift_pad: u32,
    /// Up-sample the SIFT input ×2 (first octave −1) [spec §4.1: true, OpenCV's default].
    pub sift_upsample: bool,

    // ----- tracking (§2.13-2.15) -----
    /// D_near of the distance rule (step 5), pixels [spec A9: 15 = w/2].
    pub d_near: f64,
    /// Separation needs at least this many pool matches [spec: 1].
    pub separation_min_matches: usize,

    // ----- termination (§2.16) -----
    /// Exit rule: frames of history d_K [spec: 10].
    pub exit_frames: usize,
    /// Stuck rule: frames of history d_K [spec: 50].
    pub stuck_frames: usize,
    /// Distance under which a target counts as not moving, pixels [spec: 3].
    pub still_px: f64,
    /// Lost rule: consecutive frames without a region [spec: 10].
    pub lost_frames: usize,

    // ----- extensions -----
    /// Coherent grouping of adjacent moving points before creating a target (§2.15) \[ext\].
    pub coherent_grouping: bool,
    /// Coherent grouping: largest relative difference of displacement lengths [ext: 0.3].
    pub group_len_tol: f64,
    /// Coherent grouping: largest angle between displacements, degrees [ext: 30].
    pub group_angle_deg: f64,
    /// Grouping radius: moving points whose minima lie within this many pixels of the first
    /// one (horizontally `box_w`, vertically `box_h` times this factor) are grouped even when
    /// their regions are not adjacent [ours, `robust`: 0.5 — at σ ≈ 0.27 w a person's blurred
    /// image often holds two minima whose basins are separated by a thin background basin;
    /// 0 = adjacency only, the spec's rule].
    pub group_box_frac: f64,
    /// Occluded targets located by voting with the stored offsets δ (§2.14) \[ext\].
    pub offset_voting: bool,
    /// Region gate: drop a region whose minimum lies outside a `gate_w`·w × `gate_h`·h box
    /// around the previous centre [ext: on in `robust`].
    pub region_gate: bool,
    /// Region gate width in box widths [ext: 2].
    pub gate_w: f64,
    /// Region gate height in box heights [ext: 1.5].
    pub gate_h: f64,
    /// No new target whose box centre would lie within this fraction of a box of a live
    /// target's centre (a second minimum of a person already tracked) [ours, `robust`: 0.5 —
    /// the paper creates a target for every unowned moving point, which on real video doubles
    /// people whose blurred image keeps two minima (spec A7); 0 = off].
    pub min_new_separation: f64,
    /// Fuse two visible targets whose boxes overlap with IoU at least this for `fuse_frames`
    /// consecutive frames: the younger is absorbed by the older (regions joined, the older's id
    /// and pool kept) [ours, `robust`: 0.5 — the IoU at which the evaluation would match both
    /// boxes to one person; on real video one person often ends up followed by two targets
    /// (two minima after the blur, a fragment that started its own target, spec A7); occluded
    /// targets are never fused; 0 = off].
    pub fuse_iou: f64,
    /// Consecutive frames of overlap before a fusion [ours, `robust`: 3 — a short confirmation,
    /// well under the N = 10 frames a new target needs].
    pub fuse_frames: usize,
    /// Report a target only from this many frames after its creation [ours, `robust`: 0 — off;
    /// the paper reports from the detection frame].
    pub report_after: usize,

    // ----- real-video extensions: a background model (docs/video-tracker.md) -----
    /// Fit each reported box to the target's foreground pixels \[ext, ours; `robust`: true\]:
    /// the foreground (`|I − B| > fg_threshold` against a running median background,
    /// `quarry_vision::MedianBackground`) inside a window of ±`fg_window` boxes around O_c,
    /// restricted to pixels of the target's own regions or of regions no other target owns;
    /// the box spans the `fg_trim`..1−`fg_trim` quantiles of their columns and rows. The
    /// paper's box is fixed (30×80 around the mean of the minima); on PETS09 people range from
    /// about 20×50 to 45×95 px and the darkest points sit on the torso, so a fixed box around
    /// the minima misses IoU 0.5 on most correctly tracked people (docs/video-tracker.md,
    /// diagnosis 1-2). Tracking (centres, regions, pools) is unchanged; only the reported box
    /// differs. Off = the fixed box.
    pub fg_box: bool,
    /// Do not report a visible target whose own regions hold fewer than `fg_min_frac`·w·h
    /// foreground pixels in its window, and terminate it after `lost_frames` such frames
    /// \[ext, ours;
    /// `robust`: true\] — a target whose regions froze on static background (a sign, a lamp
    /// post, the spot a person left) has no foreground; a moving person always has.
    pub fg_gate: bool,
    /// Selective background update \[ext, ours; `robust`: true\]: when a sample is taken, the
    /// pixels inside the boxes reported in the previous frame by targets that have moved
    /// (their centre was once half a box width from where it started) keep the background's
    /// value instead of the frame's, so a tracked person who stops stays foreground instead of
    /// being absorbed after half the ring (docs/video-tracker.md, diagnosis 6). Targets that
    /// never moved hold nothing: a target born on a ghost (foreground left where someone
    /// stood while the background warmed up) would otherwise keep its ghost for ever.
    pub bg_selective: bool,
    /// The stuck rule (§2.16) spares a target that has moved (see `bg_selective`) and is
    /// reported with foreground support this frame \[ext, ours; `robust`: true\]: with
    /// `fg_gate` and `bg_selective` a target whose
    /// regions froze on background has no foreground and ends through the gate, while a
    /// target on a person standing still keeps foreground and would otherwise be ended after
    /// `stuck_frames` frames (and started again with a new id).
    pub stuck_needs_no_fg: bool,
    /// Background model: samples in the ring (odd) \[ours, `robust`: 9 — with `bg_every` = 4
    /// the ring spans 36 frames, so a person crossing a pixel in under ~18 frames (w/v < 18,
    /// i.e. faster than ≈ 1.8 px/frame for w = 32, the order of the moving-point test's own
    /// ≈ 1 px/frame detection limit, spec §2.8) never enters the background\].
    pub bg_samples: usize,
    /// Background model: one sample every this many frames [ours, `robust`: 4, see
    /// `bg_samples`].
    pub bg_every: usize,
    /// Foreground threshold on `|I − B|`, grey levels [ours, `robust`: 20 — about 4σ of the
    /// noise of compressed 8-bit video (σ ≈ 4-5 levels), the 4σ of OpenCV MOG2's default
    /// `varThreshold` = 16 on squared distances, and well below the 60-100 level contrast of
    /// dark clothes on the ground the paper assumes].
    pub fg_threshold: u8,
    /// Half-size of the search window around O_c, in boxes [ours, `robust`: 0.75 — O_c is the
    /// mean of the minima, on the torso or head; the whole person lies within ±0.75 h of it].
    pub fg_window: f64,
    /// Fewest foreground pixels of the target's own regions for a fit, as a fraction of w·h
    /// [ours, `robust`: 0.1 — a tenth of a person; fewer is noise or a sliver].
    pub fg_min_frac: f64,
    /// Quantile trimmed at each side of the fitted box [ours, `robust`: 0.02 — isolated
    /// foreground noise must not stretch the box].
    pub fg_trim: f64,
    /// The fitted box's sides stay within [1/s, s] times the configured box [ours, `robust`:
    /// 1.6 — covers people from 0.6 to 1.6 times the typical size; a wider blob is a group,
    /// and its box is then centred as close to O_c as the blob allows].
    pub fg_max_scale: f64,
    /// The fitted box's width stays at most this times `box_w / box_h` times its fitted
    /// height [ours, `robust`: 1.3 — perspective scales a person's width and height together,
    /// and a walking person with spread legs or arms reaches about 1.3 times the typical
    /// aspect; a blob wider than that at a person's height is a group, and the box keeps to the
    /// part nearest O_c].
    pub fg_max_aspect: f64,
    /// Foreground births \[ext, ours; `robust`: true\]: foreground that no target's box covers,
    /// forming a blob of at least `birth_min_frac`·w·h pixels and half a person's height, seen
    /// at overlapping places (IoU ≥ 0.3) in `birth_frames` consecutive frames, starts a target
    /// on the unowned watershed regions whose minima lie in the blob. The paper creates targets
    /// only from regularly moving minima (eqs. 6-7); on PETS09 that misses people brighter than
    /// the ground (no minimum on them), people standing or walking slowly, and the second
    /// person of a pair whose blurred images share one minimum (docs/video-tracker.md).
    pub fg_births: bool,
    /// Foreground births wait while an occluded target is near \[ext, ours; `robust`: true\]:
    /// a birth blob within one box (`box_w` horizontally, `box_h` vertically) of an occluded
    /// target's box is not born. A person re-emerging from a group is one of its members, and
    /// separation (§2.15) or step 6's ownership test against the members' pools hands the
    /// person's regions back to their own track; a birth, which asks no pool, took B from its
    /// occluded track at the A/B crossing of walkers-v1 (docs/video-tracker.md, finding 3).
    pub births_wait_for_occluded: bool,
    /// An occluded target holds the region it is located in \[ext, ours; `robust`: true\]:
    /// when offset voting (`offset_voting`) locates an occluded target in a region next to the
    /// group's region that holds foreground (with the background model) and is no other
    /// target's successor region, the target also holds that region. Without it the located
    /// centre leaves the group's region, the group dissolves, and the target holds only the
    /// group's region, which its partner wins: the target is lost (finding 3).
    pub occluded_hold_located: bool,
    /// A lost person's id comes back \[ext, ours; `robust`: true\]: a target reported for the
    /// first time takes the id of a *lost* target — one that ended, or is alive but not
    /// reported this frame, and was last reported at most `lost_frames` frames ago — when its
    /// box centre lies within `box_w` (one typical person width) of where the lost target's
    /// last box would be now, moved at the velocity of its last five reported boxes; nearest
    /// pairs first, each lost id at most once. A box that only repeats the target's last one
    /// is no observation and is left out of "its last boxes": the target was occluded, held
    /// only the occlusion's regions, its pool located it nowhere (§2.14, so its centre stayed
    /// put) and no box was fitted to its foreground; the place and velocity are then those of
    /// its last observed boxes, and the window still counts from its last report (stop 38: a
    /// walker hidden behind a pair for 14 frames was predicted standing where it was hidden).
    /// A live lost target whose id is taken ends (its person is the new target's). On PETS09-S2L1 a
    /// person whose target loses its regions or its foreground for a few frames (a crossing, a
    /// group) comes back as a new target a few frames later, a few pixels from where they were
    /// going: a new id each time. The peers' ByteTrack keeps lost tracks for re-association the
    /// same way (for 1 s); here the window is `lost_frames`, the time the paper already keeps a
    /// target without regions alive, and the gate one box width: no new number. Only the reported
    /// ids change; the targets' own `id`s, their pools and all tracking steps are as without it.
    pub recall_ids: bool,
    /// A target that lost its regions takes one back \[ext, ours; `robust`: true\]: a target
    /// without regions (not occluded, not a companion) claims the region under its centre O_c
    /// when that region holds foreground (at least `fg_min_frac`/4 · w·h pixels, with the
    /// background model), has no moving point this frame, no other target continues into it
    /// (as a primary successor), and it passes step 4's SIFT ownership test against the
    /// target's pool (ratio > `tau_split`: the region is the target's person). The claim comes
    /// last in step 7's priority, so a region any other target claims stays that target's,
    /// and the target takes its region back once the other target has moved off it. With it
    /// the stuck rule (§2.16) leaves a target without regions to the lost rule
    /// (`lost_frames`): it is lost, not frozen on background. Without it a target whose
    /// regions another target took (a walker passing in front of a person standing still) has
    /// no way back: it ends, and its person, standing, makes no moving point for a new target
    /// (docs/video-tracker.md, stop 39). A moving region is left to step 6 and `recall_ids`,
    /// which check the motion. No new number: the foreground count, the ownership test, the
    /// priority and the lost window are the tracker's own.
    pub reacquire: bool,
    /// Background regions take no part in steps 4 and 6 \[ext, ours; `robust`: true\]: a
    /// region holding fewer than `fg_min_frac`/4 · w·h foreground pixels is not a candidate
    /// fragment for the SIFT ownership test (step 4) and its moving point neither joins nor
    /// starts a target (step 6). A person's fragment or moving minimum lies on foreground;
    /// static background cannot belong to a target. Spec §2.10 makes SIFT the largest cost,
    /// and most fragments are background ("SIFT only where needed").
    pub fg_skip_background: bool,
    /// People walking side by side \[ext, ours; `robust`: true; needs `fg_box`\]: when the
    /// foreground a target's box is fitted to is as wide as two people at the fitted height
    /// and has a gap between two person-high parts, the target's box is fitted to its own part
    /// only, and after `birth_frames` consecutive such frames a *companion* target with its
    /// own identity is reported on the other part for as long as the pair lasts. Two people
    /// closer than about 2σ blur into one minimum and one basin, so the paper's machinery
    /// sees one target (on PETS09-S2L1 a pair walks side by side for 160 frames: about a
    /// quarter of the ground-truth boxes, docs/video-tracker.md, diagnosis 4). No new number:
    /// the test looks for the pair within `fg_max_aspect` + 1/`fg_max_scale` typical widths
    /// (the widest single person plus the narrowest one, at the fitted height) on each side
    /// of O_c; the foreground there is at least two narrowest people (2/`fg_max_scale` typical
    /// widths) wide — stop 33; the widest-plus-narrowest width required before missed slim
    /// pairs with a clear gap, docs/video-tracker.md — each part at least
    /// 1/`fg_max_scale` typical widths wide with a column holding half the fitted height (a
    /// person's torso, not a bag or a shadow), the gap column under half the lower part's
    /// peak; only pixels darker than the background count in this test (every target is a
    /// dark minimum; the ghost of a walking person in a background model that has not caught
    /// up trails it like a second person but is brighter than the model);
    /// the companion is created only if the other part moved with the target's part over
    /// those frames (a ghost left in the background stays put), and it keeps to the part
    /// nearer its last place. A companion holds no watershed region (it has none of its own:
    /// that is the failure), takes no part in steps 1-8, is not reported while its pair is
    /// not seen and ends `lost_frames` frames after that; `min_new_separation` counts its
    /// centre, so a moving point on its person starts no second target while it lives.
    /// Occlusion groups (stop 33): two targets tracked through an occlusion on the same
    /// regions get no fit of their own; when their foreground passes the same pair test
    /// (centred between them, at the height of their last fits) each is fitted to one part,
    /// the assignment keeping each nearer its last reported box. Groups of three or more, and
    /// pairs without a gap, keep their last fits as before.
    pub fg_pairs: bool,
    /// A pair that touches stays a pair \[ext, ours; `robust`: true; needs `fg_pairs`\]: when a
    /// target whose companion was reported in the previous frame has foreground still two
    /// people wide with a person-high part on each side, but no gap between them (the two
    /// walk shoulder to shoulder), the pair is cut where it was cut in the previous frame
    /// (midway between the two last boxes, moved with the target's centre) instead of being
    /// given up. Without it the companion is hidden from the first frame the gap closes and
    /// ends `lost_frames` later (on PETS09-S2L1 the red jacket and the black coat touch in
    /// frames ≈ 105-110 and 136-178: one of them unboxed, docs/video-tracker.md, diagnosis
    /// 4). Every other condition of the pair test holds as before (each part at most one
    /// person wide and with a column holding half the fitted height); no new number, and a
    /// pair is never *started* without a gap.
    pub fg_pairs_hold: bool,
    /// A group member's companion is a third person \[ext, ours; `robust`: true; needs
    /// `fg_pairs`\]: when a two-member occlusion group's foreground passes the pair test and one
    /// member hosts a companion (the group holds three people, two of them visible), the two
    /// parts go to the two of the three — the members at their last reported boxes, the
    /// companion at its last place — that lie nearest them (the least total distance). The
    /// companion is reported on its part as on its host's pair; a member left without a part
    /// is hidden behind the others and not reported until it is seen again. Without it the
    /// companion gets no part (its host, occluded, has no pair test of its own), is hidden and
    /// ends, and the two members take the two visible people: on PETS09-S2L1 frames 156-172 a
    /// walker passing behind the red jacket and the black coat moves both members one person
    /// along (docs/video-tracker.md, "The three-person chain"). No new number.
    pub fg_pairs_group_companion: bool,
    /// Smallest uncovered foreground blob for a birth, as a fraction of w·h [ours, `robust`:
    /// 0.3 — a silhouette fills about 60 % of its box; half of it must be uncovered].
    pub birth_min_frac: f64,
    /// Consecutive frames a birth candidate must persist [ours, `robust`: 3 — like the fusion
    /// confirmation, short against the N = 10 frames of the moving-point test, long enough to
    /// reject single-frame noise and flicker].
    pub birth_frames: usize,
}

impl Default for WatershedSiftConfig {
    fn default() -> Self {
        Self::paper()
    }
}

impl WatershedSiftConfig {
    /// The `paper` profile: the values of spec §3.1-3.2, every extension off.
    pub fn paper() -> Self {
        Self {
            preset: Profile::Paper,
            sigma: 8.0,
            levels: 256,
            polarity: Polarity::Dark,
            box_w: 30.0,
            box_h: 80.0,
            n: 10,
            m_thred: 0.0,
            v_thred: 0.01,
            d_thred: 150.0,
            ratio: 0.5,
            ratio_on_squared: false,
            w_del: -7.0,
            pool_cap: 1000,
            tau_split: 0.48,
            n_min: 1,
            sift_pad: 24,
            sift_upsample: true,
            d_near: 15.0,
            separation_min_matches: 1,
            exit_frames: 10,
            stuck_frames: 50,
            still_px: 3.0,
            lost_frames: 10,
            coherent_grouping: false,
            group_len_tol: 0.3,
            group_angle_deg: 30.0,
            group_box_frac: 0.0,
            offset_voting: false,
            region_gate: false,
            gate_w: 2.0,
            gate_h: 1.5,
            min_new_separation: 0.0,
            fuse_iou: 0.0,
            fuse_frames: 3,
            report_after: 0,
            fg_box: false,
            fg_gate: false,
            bg_selective: false,
            stuck_needs_no_fg: false,
            bg_samples: 9,
            bg_every: 4,
            fg_threshold: 20,
            fg_window: 0.75,
            fg_min_frac: 0.1,
            fg_trim: 0.02,
            fg_max_scale: 1.6,
            fg_max_aspect: 1.3,
            fg_births: false,
            births_wait_for_occluded: false,
            occluded_hold_located: false,
            recall_ids: false,
            reacquire: false,
            fg_skip_background: false,
            fg_pairs: false,
            fg_pairs_hold: false,
            fg_pairs_group_companion: false,
            birth_min_frac: 0.3,
            birth_frames: 3,
        }
    }

    /// The `robust` profile: `paper` plus the spec's extensions (coherent grouping, offset
    /// voting, n_min = 3, region gate) and this implementation's real-video fixes.
    pub fn robust() -> Self {
        Self {
            preset: Profile::Robust,
            n_min: 3,
            coherent_grouping: true,
            group_box_frac: 0.5,
            offset_voting: true,
            region_gate: true,
            min_new_separation: 0.5,
            fuse_iou: 0.5,
            fg_box: true,
            fg_gate: true,
            fg_births: true,
            births_wait_for_occluded: true,
            occluded_hold_located: true,
            recall_ids: true,
            reacquire: true,
            fg_skip_background: true,
            fg_pairs: true,
            fg_pairs_hold: true,
            fg_pairs_group_companion: true,
            bg_selective: true,
            stuck_needs_no_fg: true,
            ..Self::paper()
        }
    }

    /// This configuration for a sequence whose typical person is `w` × `h` pixels (spec §5.4):
    /// the box becomes `w` × `h`, σ = w·8/30 (the paper's ratio), and D_near = w/2 (spec A9).
    pub fn with_person_size(mut self, w: f64, h: f64) -> Self {
        self.box_w = w;
        self.box_h = h;
        self.sigma = w * 8.0 / 30.0;
        self.d_near = w / 2.0;
        self
    }

    /// The moving-point test of these parameters.
    pub fn motion_test(&self) -> MotionTest {
        MotionTest {
            n: self.n,
            m_thred: self.m_thred,
            v_thred: self.v_thred,
        }
    }

    /// The background model's parameters (`bg_samples`, `bg_every`, `fg_threshold`).
    pub fn background_params(&self) -> MedianBackgroundParams {
        MedianBackgroundParams {
            samples: self.bg_samples,
            every: self.bg_every,
            threshold: self.fg_threshold,
        }
    }

    /// The pool parameters of these parameters.
    pub fn pool_params(&self) -> PoolParams {
        PoolParams {
            d_thred: self.d_thred,
            ratio: self.ratio,
            ratio_on_squared: self.ratio_on_squared,
            delete_below: self.w_del,
            cap: self.pool_cap,
            ..PoolParams::default()
        }
    }
}

impl crate::TrackerConfig for WatershedSiftConfig {
    type Preset = Profile;
    const NAME: &'static str = "watershed_sift";

    fn preset(p: Profile) -> Self {
        match p {
            Profile::Paper => Self::paper(),
            Profile::Robust => Self::robust(),
        }
    }

    fn validate(&self) -> Result<(), TrackerError> {
        let err = |r: String| Err(TrackerError::config("watershed_sift", r));
        if !(self.sigma.is_finite() && self.sigma > 0.0 && self.sigma <= MAX_SIGMA) {
            return err(format!(
                "sigma must be in (0, {MAX_SIGMA}], got {}",
                self.sigma
            ));
        }
        if !(8..=65536).contains(&self.levels) {
            return err(format!("levels must be in 8..=65536, got {}", self.levels));
        }
        for (name, v) in [("box_w", self.box_w), ("box_h", self.box_h)] {
            if !(v.is_finite() && (2.0..=MAX_BOX_SIDE).contains(&v)) {
                return err(format!("{name} must be in [2, {MAX_BOX_SIDE}], got {v}"));
            }
        }
        if !(2..=MAX_N).contains(&self.n) {
            return err(format!("n must be in 2..={MAX_N}, got {}", self.n));
        }
        for (name, v) in [
            ("m_thred", self.m_thred),
            ("v_thred", self.v_thred),
            ("d_near", self.d_near),
            ("still_px", self.still_px),
            ("group_len_tol", self.group_len_tol),
            ("group_angle_deg", self.group_angle_deg),
            ("group_box_frac", self.group_box_frac),
            ("gate_w", self.gate_w),
            ("gate_h", self.gate_h),
            ("min_new_separation", self.min_new_separation),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return err(format!("{name} must be finite and >= 0, got {v}"));
            }
        }
        if !(self.fg_window.is_finite() && self.fg_window > 0.0 && self.fg_window <= 10.0) {
            return err(format!(
                "fg_window must be in (0, 10], got {}",
                self.fg_window
            ));
        }
        for (name, v) in [
            ("fg_min_frac", self.fg_min_frac),
            ("fg_trim", self.fg_trim),
            ("birth_min_frac", self.birth_min_frac),
        ] {
            if !(v.is_finite() && (0.0..0.5).contains(&v)) {
                return err(format!("{name} must be in [0, 0.5), got {v}"));
            }
        }
        if !(self.fg_max_aspect.is_finite() && (0.1..=100.0).contains(&self.fg_max_aspect)) {
            return err(format!(
                "fg_max_aspect must be in [0.1, 100], got {}",
                self.fg_max_aspect
            ));
        }
        if self.birth_frames == 0 || self.birth_frames > MAX_FRAMES_RULE {
            return err(format!(
                "birth_frames must be in 1..={MAX_FRAMES_RULE}, got {}",
                self.birth_frames
            ));
        }
        if !(self.fg_max_scale.is_finite() && (1.0..=100.0).contains(&self.fg_max_scale)) {
            return err(format!(
                "fg_max_scale must be in [1, 100], got {}",
                self.fg_max_scale
            ));
        }
        self.background_params().validate().map_err(|e| {
            TrackerError::config(
                "watershed_sift",
                format!("background (bg_samples, bg_every): {e}"),
            )
        })?;
        if !(self.fuse_iou.is_finite() && (0.0..=1.0).contains(&self.fuse_iou)) {
            return err(format!("fuse_iou must be in [0, 1], got {}", self.fuse_iou));
        }
        if !(self.tau_split.is_finite() && (0.0..=1.0).contains(&self.tau_split)) {
            return err(format!(
                "tau_split must be in [0, 1], got {}",
                self.tau_split
            ));
        }
        if self.n_min == 0 {
            return err("n_min must be >= 1".into());
        }
        if self.sift_pad > 1024 {
            return err(format!(
                "sift_pad must be at most 1024, got {}",
                self.sift_pad
            ));
        }
        for (name, v) in [
            ("exit_frames", self.exit_frames),
            ("stuck_frames", self.stuck_frames),
            ("lost_frames", self.lost_frames),
            ("report_after", self.report_after),
            ("fuse_frames", self.fuse_frames),
        ] {
            if v > MAX_FRAMES_RULE {
                return err(format!("{name} must be at most {MAX_FRAMES_RULE}, got {v}"));
            }
        }
        if self.exit_frames == 0 || self.stuck_frames == 0 {
            return err("exit_frames and stuck_frames must be >= 1".into());
        }
        self.pool_params()
            .validate()
            .map_err(|e| TrackerError::config("watershed_sift", e.to_string()))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PresetName, TrackerConfig};

    #[test]
    fn presets_are_valid_and_round_trip() {
        for p in Profile::ALL {
            let c = WatershedSiftConfig::preset(*p);
            c.validate().unwrap();
            let t = c.to_toml().unwrap();
            assert_eq!(WatershedSiftConfig::from_toml(&t, None).unwrap(), c);
        }
        assert_eq!(WatershedSiftConfig::default(), WatershedSiftConfig::paper());
        let r = WatershedSiftConfig::from_toml("preset = \"robust\"\nsigma = 9.0\n", None).unwrap();
        assert_eq!(r.n_min, 3);
        assert_eq!(r.sigma, 9.0);
        assert_eq!(Profile::parse("robust").unwrap(), Profile::Robust);
    }

    #[test]
    fn unknown_keys_and_bad_values_are_named() {
        let e = WatershedSiftConfig::from_toml("x = 1\nsigmaa = 2.0\n", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 1") || e.contains("line 2"), "{e}");
        for (toml, name) in [
            ("sigma = -1.0", "sigma"),
            ("box_w = 0.0", "box_w"),
            ("tau_split = 2.0", "tau_split"),
            ("n = 1", "n"),
            ("d_thred = 0.0", "d_thred"),
            ("n_min = 0", "n_min"),
            ("bg_samples = 4", "bg_samples"),
            ("fg_window = 0.0", "fg_window"),
            ("fg_max_scale = 0.5", "fg_max_scale"),
        ] {
            let e = WatershedSiftConfig::from_toml(toml, None)
                .unwrap_err()
                .to_string();
            assert!(e.contains(name), "{toml}: {e}");
        }
    }

    #[test]
    fn person_size_sets_box_sigma_and_d_near() {
        let c = WatershedSiftConfig::paper().with_person_size(36.0, 90.0);
        assert_eq!((c.box_w, c.box_h), (36.0, 90.0));
        assert!((c.sigma - 9.6).abs() < 1e-12);
        assert_eq!(c.d_near, 18.0);
        let p = WatershedSiftConfig::paper().with_person_size(30.0, 80.0);
        assert_eq!(p, WatershedSiftConfig::paper());
    }
}
