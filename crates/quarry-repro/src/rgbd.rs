//! Paper 001: the RGB-D person tracker ([`quarry_trackers::rgbd_person`]) on the synthetic
//! scenarios S1-S6 of [`quarry_sim::rgbd`] (spec 001 §6.2), with a per-frame record of every
//! run ([`FrameRecord`]), the §5.4 measures ([`ScenarioSummary`], [`summarise`]) and the
//! template drift score ([`template_drift`]).
//!
//! [`run_scenario`] runs one configuration; [`run_scenario_multi`] runs several on the same
//! rendered frames (each run's result is exactly that of [`run_scenario_frames`] alone).
//!
//! ```
//! use quarry_core::{SingleTargetTracker, Stamp};
//! use quarry_repro::rgbd::{OdometryFeed, rgbd_frame, run_scenario_frames};
//! use quarry_sim::rgbd::{RgbdScene, ScenarioId};
//! use quarry_trackers::rgbd_person::{RgbdPersonConfig, RgbdPersonTracker};
//! let scene = RgbdScene::new(ScenarioId::S2Scale, 0)?;
//! // one step by hand on the rendered frames ...
//! let mut tr = RgbdPersonTracker::new(RgbdPersonConfig::paper())?;
//! let f0 = scene.render(0)?;
//! let b0 = f0.truth.amodal.unwrap();
//! tr.init(Stamp::from_frame(0, scene.dt), &rgbd_frame(&scene, f0)?, b0)?;
//! let f1 = scene.render(1)?;
//! let truth = f1.truth.amodal.unwrap();
//! let out = tr.step(Stamp::from_frame(1, scene.dt), &rgbd_frame(&scene, f1)?)?;
//! assert!(out.bbox.unwrap().iou(&truth) > 0.5);
//! // ... or the scenario runner, which also scores the run
//! let (summary, frames) =
//!     run_scenario_frames(&scene, 0, &RgbdPersonConfig::paper(), OdometryFeed::Exact, 5, |_, _| {})?;
//! assert_eq!(frames.len(), 4);
//! assert!(summary.success_rate_iou50 > 0.9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use quarry_core::{BBox, CoreError, EgoMotion, SingleTargetTracker, Stamp};
use quarry_sim::rgbd::{RgbdSample, RgbdScene};
use quarry_trackers::TrackerError;
use quarry_trackers::rgbd_person::{
    OcclusionState, RgbdPersonConfig, RgbdPersonTracker, TrackOutput,
};
use quarry_vision::multicue::{PatchMultiCueModel, RgbdFrame};
use serde::{Deserialize, Serialize};

use crate::ReproError;

/// The tracker's input for a rendered frame of `scene` (no odometry: set
/// [`RgbdFrame::ego`] for a moving robot).
///
/// # Errors
/// The rendered RGB and depth do not fit the scene's image size (a simulator bug).
pub fn rgbd_frame(scene: &RgbdScene, sample: RgbdSample) -> Result<RgbdFrame, ReproError> {
    RgbdFrame::new(
        scene.intrinsics.width,
        scene.intrinsics.height,
        sample.rgb,
        sample.depth_m,
        EgoMotion::None,
    )
    .map_err(|e| TrackerError::Vision(e).into())
}

/// Odometry fed to the tracker in a synthetic run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum OdometryFeed {
    /// The exact increment.
    #[default]
    Exact,
    /// The increment with 5 % proportional noise.
    Noisy,
}

/// Per-frame record of a scenario run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// Frame index.
    pub frame: usize,
    /// Output box (`None` in `Lost`).
    pub bbox: Option<BBox>,
    /// A detection was accepted.
    pub confirmed: bool,
    /// Occlusion state.
    pub state: OcclusionState,
    /// Ground-truth amodal box.
    pub gt: Option<BBox>,
    /// Ground-truth visibility.
    pub visibility: f64,
    /// IoU of the output with the amodal box (0 without output).
    pub iou: f64,
    /// Centre error, pixels (`None` without output or ground truth).
    pub centre_err: Option<f64>,
    /// Template histograms updated.
    pub n_updated: usize,
    /// MEKF position error against the ground-truth robot-frame point, metres.
    pub pos_err_m: f64,
    /// IoU with the distractor (S5), 0 otherwise.
    pub iou_distractor: f64,
    /// `H_out / (c_base·H_gt)`: output box height over the shrunk ground-truth height (S2's
    /// scale check; `None` without output or ground truth).
    pub height_ratio: Option<f64>,
    /// On the first frame after an occlusion episode (a run of frames with visibility < 0.8),
    /// the episode's template drift score: [`template_drift`] between the templates just before
    /// and just after it.
    pub drift: Option<f64>,
    /// Step time, milliseconds (wall clock, informative only).
    pub ms: f64,
}

/// The template drift score of spec 001 §5.4 (b) between two templates: the mean, over the
/// patches valid in `before` and the cues (colour, texture) held by both, of the cosine between
/// the two histograms. 1 means unchanged. `None` when no histogram pair exists.
///
/// # Errors
/// Templates of different grids (patch counts) or histograms of different lengths.
pub fn template_drift(
    before: &PatchMultiCueModel,
    after: &PatchMultiCueModel,
) -> Result<Option<f64>, ReproError> {
    let (bc, bt) = before.template();
    let (ac, at) = after.template();
    if bc.len() != ac.len() || bt.len() != at.len() || before.valid().len() != bc.len() {
        return Err(CoreError::invalid(
            "template drift",
            format!(
                "templates of different grids ({} and {} patches)",
                bc.len(),
                ac.len()
            ),
        )
        .into());
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for (k, &valid) in before.valid().iter().enumerate() {
        if !valid {
            continue;
        }
        for (b, a) in [(&bc[k], &ac[k]), (&bt[k], &at[k])] {
            if let (Some(b), Some(a)) = (b, a) {
                sum += f64::from(b.cosine(a).map_err(TrackerError::Vision)?);
                n += 1;
            }
        }
    }
    #[allow(clippy::cast_precision_loss)]
    Ok((n > 0).then(|| sum / n as f64))
}

/// Summary of a scenario run (spec §5.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScenarioSummary {
    /// Scenario name.
    pub scenario: String,
    /// Seed.
    pub seed: u64,
    /// Mean centre error over frames with visibility ≥ 0.5 and an output, pixels.
    pub center_err_px: f64,
    /// Success rate at IoU 0.5 over frames with visibility ≥ 0.5.
    pub success_rate_iou50: f64,
    /// Worst recovery latency over full-occlusion episodes (frames; `None` = never recovered;
    /// 0 when there is no episode).
    pub recovery_frames: Option<usize>,
    /// Template updates on frames with visibility < 0.6.
    pub updates_low_visibility: usize,
    /// Fraction of frames with visibility < 0.1 reported as Full/Severe occlusion or Lost.
    pub occlusion_recall: Option<f64>,
    /// 3-D RMSE of the MEKF position over frames with visibility ≥ 0.5, metres.
    pub rmse_3d_m: f64,
    /// Frames whose output overlaps the distractor more than the target (S5).
    pub distractor_frames: usize,
    /// Frames in `Lost`.
    pub lost_frames: usize,
    /// Mean template drift score over the occlusion episodes (`None` without an episode; S1:
    /// ≥ 0.95).
    pub drift_score: Option<f64>,
    /// Fraction of the frames after frame 5 with an output whose `H_out / (c_base·H_gt)` is
    /// within ±10 % (S2: ≥ 0.95; frames without an output count as outside).
    pub height_within_10pct: Option<f64>,
    /// Centre error of the output at the end of the S6 blackout (frame 130), pixels.
    pub blackout_end_err_px: Option<f64>,
    /// Mean step time, ms (wall clock, informative; see the criterion bench for speed).
    pub ms_per_frame: f64,
}

/// Runs the tracker on a synthetic scenario, initialised from frame 0's amodal box.
///
/// # Errors
/// A simulator or tracker error ([`ReproError::Sim`], [`ReproError::Tracker`]).
pub fn run_scenario(
    scene: &RgbdScene,
    seed: u64,
    cfg: &RgbdPersonConfig,
    odometry: OdometryFeed,
    on_frame: impl FnMut(&RgbdSample, &TrackOutput),
) -> Result<(ScenarioSummary, Vec<FrameRecord>), ReproError> {
    run_scenario_frames(scene, seed, cfg, odometry, scene.len(), on_frame)
}

/// [`run_scenario`] over the first `n_frames` frames only (e.g. a quick demo).
///
/// # Errors
/// A simulator or tracker error ([`ReproError::Sim`], [`ReproError::Tracker`]).
pub fn run_scenario_frames(
    scene: &RgbdScene,
    seed: u64,
    cfg: &RgbdPersonConfig,
    odometry: OdometryFeed,
    n_frames: usize,
    mut on_frame: impl FnMut(&RgbdSample, &TrackOutput),
) -> Result<(ScenarioSummary, Vec<FrameRecord>), ReproError> {
    let mut runs = run_scenario_multi(
        scene,
        seed,
        &[(cfg.clone(), odometry)],
        n_frames,
        |_, smp, o| on_frame(smp, o),
    )?;
    runs.pop()
        .ok_or_else(|| ReproError::Invalid("run_scenario_multi returned no run".into()))
}

/// Runs several trackers (configuration and odometry feed each) on the same scenario, rendering
/// each frame once: the result of each run is exactly that of [`run_scenario_frames`] with its
/// configuration (the trackers share nothing but the rendered frames). `on_frame` receives the
/// run's index.
///
/// # Errors
/// A simulator or tracker error ([`ReproError::Sim`], [`ReproError::Tracker`]).
#[allow(clippy::cast_precision_loss, clippy::too_many_lines)]
pub fn run_scenario_multi(
    scene: &RgbdScene,
    seed: u64,
    runs: &[(RgbdPersonConfig, OdometryFeed)],
    n_frames: usize,
    mut on_frame: impl FnMut(usize, &RgbdSample, &TrackOutput),
) -> Result<Vec<(ScenarioSummary, Vec<FrameRecord>)>, ReproError> {
    let mut trackers = runs
        .iter()
        .map(|(c, _)| RgbdPersonTracker::new(c.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let f0 = scene.render(0)?;
    let init = f0.truth.amodal.ok_or_else(|| {
        ReproError::Invalid(format!(
            "{}: the target is not in view at frame 0",
            scene.id().name()
        ))
    })?;
    let w = scene.intrinsics.width;
    let h = scene.intrinsics.height;
    let frame0 = rgbd_frame(scene, f0)?;
    for tr in &mut trackers {
        tr.init(Stamp::from_frame(0, scene.dt), &frame0, init)?;
    }
    drop(frame0);
    let mut recs: Vec<Vec<FrameRecord>> = runs
        .iter()
        .map(|_| Vec::with_capacity(scene.len()))
        .collect();
    // the template just before the current occlusion episode (visibility < 0.8), per run
    let mut before: Vec<Option<Option<PatchMultiCueModel>>> = vec![None; runs.len()];
    for k in 1..n_frames.min(scene.len()) {
        let smp = scene.render(k)?;
        let t = &smp.truth;
        let mut fr = RgbdFrame::new(w, h, smp.rgb.clone(), smp.depth_m.clone(), EgoMotion::None)
            .map_err(TrackerError::Vision)?;
        for (r, ((_, odometry), tr)) in runs.iter().zip(trackers.iter_mut()).enumerate() {
            fr.ego = EgoMotion::Delta(match odometry {
                OdometryFeed::Exact => t.delta,
                OdometryFeed::Noisy => t.delta_noisy,
            });
            tr.force_no_detection(t.detector_off);
            if before[r].is_none() && t.visibility < 0.8 {
                before[r] = Some(tr.template().cloned());
            }
            let t0 = std::time::Instant::now();
            let o = tr.step(Stamp::from_frame(k as u64, scene.dt), &fr)?;
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            on_frame(r, &smp, &o);
            let iou = match (o.bbox, t.amodal) {
                (Some(b), Some(g)) => b.iou(&g),
                _ => 0.0,
            };
            let centre_err = match (o.bbox, t.amodal) {
                (Some(b), Some(g)) => Some((b.cx - g.cx).hypot(b.cy - g.cy)),
                _ => None,
            };
            let gt = t.target_robot;
            let pos_err_m = (o.mean[0] - gt[0]).hypot(o.mean[1] - gt[1]);
            let drift = if t.visibility >= 0.8 {
                match (before[r].take(), tr.template()) {
                    (Some(Some(b)), Some(a)) => template_drift(&b, a)?,
                    _ => None,
                }
            } else {
                None
            };
            let c_base = tr.config().c_base;
            recs[r].push(FrameRecord {
                frame: k,
                bbox: o.bbox,
                confirmed: o.confirmed,
                state: o.state,
                gt: t.amodal,
                visibility: t.visibility,
                iou,
                centre_err,
                n_updated: o.n_updated_patches,
                pos_err_m,
                iou_distractor: match (o.bbox, t.distractor) {
                    (Some(b), Some(g)) => b.iou(&g),
                    _ => 0.0,
                },
                height_ratio: match (o.bbox, t.amodal) {
                    (Some(b), Some(g)) if g.h > 0.0 => Some(b.h / (c_base * g.h)),
                    _ => None,
                },
                drift,
                ms,
            });
        }
    }
    Ok(recs
        .into_iter()
        .map(|r| (summarise(scene.id().name(), seed, &r), r))
        .collect())
}

/// The §5.4 measures of a run.
#[must_use]
#[allow(clippy::cast_precision_loss)]
pub fn summarise(name: &str, seed: u64, recs: &[FrameRecord]) -> ScenarioSummary {
    let vis: Vec<&FrameRecord> = recs.iter().filter(|r| r.visibility >= 0.5).collect();
    let errs: Vec<f64> = vis.iter().filter_map(|r| r.centre_err).collect();
    let mean = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let success = if vis.is_empty() {
        f64::NAN
    } else {
        vis.iter().filter(|r| r.iou >= 0.5).count() as f64 / vis.len() as f64
    };
    // recovery: episodes of visibility < 0.1 lasting ≥ 3 frames
    let mut worst: Option<Option<usize>> = None;
    let mut i = 0;
    while i < recs.len() {
        if recs[i].visibility < 0.1 {
            let start = i;
            while i < recs.len() && recs[i].visibility < 0.1 {
                i += 1;
            }
            if i - start >= 3 {
                let Some(back) = (i..recs.len()).find(|&j| recs[j].visibility >= 0.5) else {
                    continue;
                };
                let mut lat = None;
                for j in back..recs.len().saturating_sub(4) {
                    if recs[j..j + 5].iter().all(|r| r.iou >= 0.5) {
                        lat = Some(j - back);
                        break;
                    }
                }
                worst = Some(match (worst, lat) {
                    (None, l) => l,
                    (Some(None), _) | (_, None) => None,
                    (Some(Some(a)), Some(b)) => Some(a.max(b)),
                });
            }
        } else {
            i += 1;
        }
    }
    let hidden: Vec<&FrameRecord> = recs.iter().filter(|r| r.visibility < 0.1).collect();
    let occ = (!hidden.is_empty()).then(|| {
        hidden
            .iter()
            .filter(|r| {
                matches!(
                    r.state,
                    OcclusionState::FullOcclusion
                        | OcclusionState::SevereOcclusion
                        | OcclusionState::Lost
                )
            })
            .count() as f64
            / hidden.len() as f64
    });
    let sq: Vec<f64> = vis.iter().map(|r| r.pos_err_m * r.pos_err_m).collect();
    ScenarioSummary {
        scenario: name.to_string(),
        seed,
        center_err_px: mean(&errs),
        success_rate_iou50: success,
        recovery_frames: worst.unwrap_or(Some(0)),
        updates_low_visibility: recs
            .iter()
            .filter(|r| r.visibility < 0.6)
            .map(|r| r.n_updated)
            .sum(),
        occlusion_recall: occ,
        rmse_3d_m: mean(&sq).sqrt(),
        distractor_frames: recs
            .iter()
            .filter(|r| r.iou_distractor > r.iou && r.iou_distractor > 0.0)
            .count(),
        lost_frames: recs
            .iter()
            .filter(|r| r.state == OcclusionState::Lost)
            .count(),
        drift_score: {
            let d: Vec<f64> = recs.iter().filter_map(|r| r.drift).collect();
            (!d.is_empty()).then(|| mean(&d))
        },
        height_within_10pct: {
            let late: Vec<&FrameRecord> = recs
                .iter()
                .filter(|r| r.frame > 5 && r.gt.is_some())
                .collect();
            (!late.is_empty()).then(|| {
                late.iter()
                    .filter(|r| r.height_ratio.is_some_and(|q| (q - 1.0).abs() <= 0.1))
                    .count() as f64
                    / late.len() as f64
            })
        },
        blackout_end_err_px: recs.iter().find(|r| r.frame == 130).and_then(|r| {
            if name.starts_with("s6") {
                r.centre_err
            } else {
                None
            }
        }),
        ms_per_frame: mean(&recs.iter().map(|r| r.ms).collect::<Vec<_>>()),
    }
}
