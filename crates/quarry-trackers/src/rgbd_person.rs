//! RGB-D person tracking on a mobile robot with a patch multi-cue model and the MEKF (spec 001).
//!
//! Per frame (spec §2.11): MEKF predict with the odometry → depth gate and projected prediction
//! → candidate grid G1 around the previous output, the MEKF candidate and its local grid G2 →
//! features over the union of candidates → describe and score every candidate → tiered
//! selection T1 / T2a / T2b / T3 → occlusion state → MEKF update, template update (eq. 12) and
//! scale (A2) only in the states that allow it. With no detection the projected prediction is
//! the output (`FullOcclusion`, then `Lost` after `lost_after` frames).
//!
//! ```
//! use quarry_core::{SingleTargetTracker, Stamp, EgoMotion};
//! use quarry_sim::rgbd::{RgbdScene, ScenarioId};
//! use quarry_trackers::rgbd_person::{RgbdPersonConfig, RgbdPersonTracker};
//! use quarry_vision::RgbdFrame;
//! let scene = RgbdScene::new(ScenarioId::S2Scale, 0)?;
//! let mut tr = RgbdPersonTracker::new(RgbdPersonConfig::paper())?;
//! let f0 = scene.render(0)?;
//! let frame = |s: quarry_sim::rgbd::RgbdSample| RgbdFrame::new(640, 480, s.rgb, s.depth_m, EgoMotion::None);
//! tr.init(Stamp::from_frame(0, scene.dt), &frame(f0.clone())?, f0.truth.amodal.unwrap())?;
//! let f1 = scene.render(1)?;
//! let out = tr.step(Stamp::from_frame(1, scene.dt), &frame(f1.clone())?)?;
//! assert!(out.bbox.unwrap().iou(&f1.truth.amodal.unwrap()) > 0.5);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Choices where the spec leaves one are listed in `docs/rgbd-person.md`.

use crate::TrackerError;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use quarry_core::{
    BBox, CameraMount, CoreError, Gaussian, PinholeIntrinsics, Pose2, SingleTargetTracker, Stamp,
    StateEstimate, StateLayout, TimeUs, TrackId, TrackReport, TrackStatus,
};
use quarry_filter::{EgoCvModel, EgoModel, Ekf, FilterError, Position3};
use quarry_vision::VisionError;
use quarry_vision::multicue::{
    CandidateScore, PatchDescriptor, PatchModelConfig, PatchMultiCueModel, RgbdFeatures, RgbdFrame,
};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Errors of the RGB-D person tracker.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RgbdError {
    /// A shared error kind.
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A descriptor / frame error.
    #[error(transparent)]
    Vision(#[from] VisionError),
    /// The MEKF failed.
    #[error(transparent)]
    Filter(#[from] FilterError),
    /// An unusable configuration.
    #[error("invalid rgbd_person configuration: {0}")]
    Config(String),
    /// `step` before `init`, or a frame that does not fit the tracker.
    #[error("{0}")]
    State(String),
}

impl From<RgbdError> for TrackerError {
    fn from(e: RgbdError) -> Self {
        match e {
            RgbdError::Core(c) => TrackerError::Core(c),
            other => TrackerError::config("rgbd_person", other.to_string()),
        }
    }
}

/// How the box size follows the target depth (A2, I6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ScaleRule {
    /// `γ = c_base·Z_0/Z_ref` on the base size, clamped to ±`scale_clamp` per frame (default).
    #[default]
    Disparity,
    /// Size never changes (`scale_frozen` ablation).
    Frozen,
}

/// Configuration (spec §3). `Default` = [`RgbdPersonConfig::paper`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RgbdPersonConfig {
    /// The appearance model (N, bins, band, th, ...).
    pub model: PatchModelConfig,
    /// `c_base` (paper: 0.9), a one-time shrink of the initial box.
    pub c_base: f64,
    /// Acceptance fraction `a` (0.8, step 6; I2).
    pub accept_fraction: f32,
    /// Severe-occlusion fraction (0.5, I3).
    pub severe_fraction: f32,
    /// Depth gate floor (0.5 m) and multiple of the predicted std (3).
    pub gate_floor_m: f64,
    /// Depth gate: multiple of `sqrt(P⁻[0,0])`.
    pub gate_sigmas: f64,
    /// White acceleration σ_w, m/s² (1.0).
    pub sigma_w: f64,
    /// Height random walk σ_h, m/√s (0.05).
    pub sigma_h: f64,
    /// Measurement noise σ_p, m (0.10).
    pub sigma_p: f64,
    /// Initial velocity std σ_v0, m/s (1.0).
    pub sigma_v0: f64,
    /// Camera intrinsics (Kinect v1 default 525, 525, 319.5, 239.5).
    pub intrinsics: PinholeIntrinsics,
    /// Camera mount (0, 0, 1.0) m, no tilt (tilt ≠ 0 is rejected).
    pub mount: CameraMount,
    /// G1 half-width in strides along u (4 → 9 columns).
    pub grid_i: i32,
    /// G1 half-height in strides along v (2 → 5 rows).
    pub grid_j: i32,
    /// Add the projected MEKF prediction as a candidate.
    pub mekf_candidate: bool,
    /// Add the 3×3 grid G2 around the MEKF candidate (I11).
    pub mekf_local_grid: bool,
    /// Per-frame relative change limit of the size (0.05).
    pub scale_clamp: f64,
    /// Scale rule.
    pub scale_rule: ScaleRule,
    /// Frames of full occlusion before `Lost` (90).
    pub lost_after: u32,
    /// `strict` preset: learn only when `m(c*) ≥` this.
    pub update_fraction: Option<f32>,
    /// Gate learning on the occlusion state (false = `no_occlusion_gate` ablation).
    pub occlusion_gate: bool,
    /// Learn only when every valid patch of `c*` is unoccluded (`U(c*) = V`: no valid patch
    /// depth-occluded, out of view or empty), on top of the state gate. A box that slid beside a
    /// partly covered target has empty patches but no occluder pixels, so `D(c*)` alone lets it
    /// learn (S1 seeds 1-2). `false` = the spec's literal state-only gate.
    pub learn_unoccluded_only: bool,
    /// Tier T2b (texture only, also inside T3) also needs `S_Ld ≥` this fraction of the
    /// template's texture self-score over the scored patches (spec §8; `None` = off). Flat,
    /// noisy surfaces (floor, panel) have riu2 histograms close to a plain shirt's, so without
    /// it T2b accepts the floor during a full occlusion and drags the MEKF off (S1 seed 2).
    pub t2b_self_score_fraction: Option<f32>,
    /// Use odometry in the MEKF (false = `no_ego` ablation).
    pub ego: bool,
    /// Use the paper's literal eq. (11) (ablation).
    pub paper_literal_11: bool,
    /// Whole-target baseline behaviour: argmax S always accepted, no occlusion reasoning,
    /// update every frame (per-cue λ > th), no MEKF candidate.
    pub baseline: bool,
    /// Optional NIS gate on the MEKF update (χ²₃ 0.999 = 16.27).
    pub gate_chi2: Option<f64>,
}

impl Default for RgbdPersonConfig {
    fn default() -> Self {
        Self::paper()
    }
}

impl RgbdPersonConfig {
    /// The spec's defaults (§3).
    #[must_use]
    pub fn paper() -> Self {
        Self {
            model: PatchModelConfig::default(),
            c_base: 0.9,
            accept_fraction: 0.8,
            severe_fraction: 0.5,
            gate_floor_m: 0.5,
            gate_sigmas: 3.0,
            sigma_w: 1.0,
            sigma_h: 0.05,
            sigma_p: 0.10,
            sigma_v0: 1.0,
            intrinsics: PinholeIntrinsics {
                fx: 525.0,
                fy: 525.0,
                cx: 319.5,
                cy: 239.5,
                width: 640,
                height: 480,
            },
            mount: CameraMount {
                t: Vector3::new(0.0, 0.0, 1.0),
                tilt: 0.0,
            },
            grid_i: 4,
            grid_j: 2,
            mekf_candidate: true,
            mekf_local_grid: true,
            scale_clamp: 0.05,
            scale_rule: ScaleRule::Disparity,
            lost_after: 90,
            update_fraction: None,
            occlusion_gate: true,
            learn_unoccluded_only: true,
            t2b_self_score_fraction: Some(0.5),
            ego: true,
            paper_literal_11: false,
            baseline: false,
            gate_chi2: None,
        }
    }

    /// `a = 0.9` and the learning gate `m(c*) ≥ 0.9`.
    #[must_use]
    pub fn strict() -> Self {
        Self {
            accept_fraction: 0.9,
            update_fraction: Some(0.9),
            ..Self::paper()
        }
    }

    /// The whole-target colour-texture baseline (§5.5).
    #[must_use]
    pub fn whole_target_baseline() -> Self {
        Self {
            model: PatchModelConfig::whole_target_baseline(),
            mekf_candidate: false,
            mekf_local_grid: false,
            occlusion_gate: false,
            baseline: true,
            ..Self::paper()
        }
    }

    /// Parses a TOML configuration (missing keys take the `paper()` values).
    ///
    /// # Errors
    /// [`RgbdError::Config`] for malformed TOML or invalid values.
    pub fn from_toml(s: &str) -> Result<Self, RgbdError> {
        let c: Self = toml::from_str(s).map_err(|e| RgbdError::Config(e.to_string()))?;
        c.validate()?;
        Ok(c)
    }

    /// Checks the parameters.
    ///
    /// # Errors
    /// [`RgbdError::Config`] naming the bad value.
    pub fn validate(&self) -> Result<(), RgbdError> {
        self.model.validate()?;
        let pos = |name: &str, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(RgbdError::Config(format!(
                    "{name} must be finite and > 0, got {x}"
                )))
            }
        };
        pos("c_base", self.c_base)?;
        pos("sigma_p", self.sigma_p)?;
        pos("sigma_v0", self.sigma_v0)?;
        pos("gate_floor_m", self.gate_floor_m)?;
        pos("gate_sigmas", self.gate_sigmas)?;
        pos("scale_clamp", self.scale_clamp)?;
        for (n, x) in [("sigma_w", self.sigma_w), ("sigma_h", self.sigma_h)] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(RgbdError::Config(format!("{n} must be ≥ 0, got {x}")));
            }
        }
        if self.c_base > 1.0 {
            return Err(RgbdError::Config(format!(
                "c_base must be ≤ 1, got {}",
                self.c_base
            )));
        }
        for (n, x) in [
            ("accept_fraction", self.accept_fraction),
            ("severe_fraction", self.severe_fraction),
            ("update_fraction", self.update_fraction.unwrap_or(0.0)),
            (
                "t2b_self_score_fraction",
                self.t2b_self_score_fraction.unwrap_or(0.0),
            ),
        ] {
            if !(0.0..=1.0).contains(&x) {
                return Err(RgbdError::Config(format!(
                    "{n} must lie in [0, 1], got {x}"
                )));
            }
        }
        let k = self.intrinsics;
        if ![k.fx, k.fy, k.cx, k.cy].iter().all(|v| v.is_finite()) || k.fx <= 0.0 || k.fy <= 0.0 {
            return Err(RgbdError::Config("intrinsics must be finite, f > 0".into()));
        }
        if self.mount.tilt != 0.0 || !self.mount.t.iter().all(|v| v.is_finite()) {
            return Err(RgbdError::Config(
                "camera mount: finite translation and tilt = 0 (tilt is not implemented)".into(),
            ));
        }
        if !(0..=20).contains(&self.grid_i) || !(0..=20).contains(&self.grid_j) {
            return Err(RgbdError::Config(
                "grid_i / grid_j must be in 0..=20".into(),
            ));
        }
        if let Some(g) = self.gate_chi2
            && !(g.is_finite() && g > 0.0)
        {
            return Err(RgbdError::Config(format!("gate_chi2 must be > 0, got {g}")));
        }
        Ok(())
    }
}

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

/// The tracker's output for one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackOutput {
    /// The frame's stamp.
    pub stamp: Stamp,
    /// Output box: the detection, or the projected prediction; `None` in `Lost`.
    pub bbox: Option<BBox>,
    /// A detection was accepted this frame.
    pub confirmed: bool,
    /// Occlusion state.
    pub state: OcclusionState,
    /// Selecting tier, if any.
    pub tier: Option<DetectionTier>,
    /// Score of the selected candidate.
    pub score: Option<CandidateScore>,
    /// Target depth of the selected candidate, metres.
    pub z_star: Option<f32>,
    /// Scale factor `γ = c_base·Z_0/Z_ref`.
    pub gamma: f64,
    /// MEKF mean `[x, y, z, ẋ, ẏ]` in the robot frame (posterior).
    pub mean: SVector<f64, 5>,
    /// MEKF covariance.
    pub cov: SMatrix<f64, 5, 5>,
    /// Number of (patch, cue) template histograms updated this frame.
    pub n_updated_patches: usize,
    /// The projected MEKF prediction (before the update), when it projects.
    pub predicted: Option<(f64, f64)>,
    /// Number of candidates scored.
    pub n_candidates: usize,
}

impl From<TrackOutput> for Option<TrackReport> {
    fn from(o: TrackOutput) -> Self {
        let status = match o.state {
            OcclusionState::Normal | OcclusionState::AppearanceChange => TrackStatus::Confirmed,
            OcclusionState::PartialOcclusion | OcclusionState::SevereOcclusion => {
                TrackStatus::Occluded
            }
            OcclusionState::FullOcclusion => TrackStatus::Coasting,
            OcclusionState::Lost => return None,
        };
        let mut r = TrackReport::new(o.stamp, TrackId(1), status);
        r.bbox = o.bbox;
        r.score = o.score.map(|s| f64::from(s.s));
        r.state = Some(StateEstimate {
            layout: StateLayout::XyzVxVy,
            mean: nalgebra::DVector::from_column_slice(o.mean.as_slice()),
            cov: Some(nalgebra::DMatrix::from_column_slice(5, 5, o.cov.as_slice())),
        });
        Some(r)
    }
}

type Mekf = Ekf<5, 3, EgoCvModel, Position3>;

/// The RGB-D person tracker (spec 001).
#[derive(Debug, Clone)]
pub struct RgbdPersonTracker {
    cfg: RgbdPersonConfig,
    model: Option<PatchMultiCueModel>,
    ekf: Option<Mekf>,
    base: (f64, f64),
    size: (f64, f64),
    z0: f64,
    z_ref: f64,
    prev: (f64, f64),
    state: OcclusionState,
    full_count: u32,
    last_t: TimeUs,
    force_off: bool,
}

/// Camera-frame point → robot frame (A1, no tilt).
fn cam_to_robot(p: &Vector3<f64>, m: &CameraMount) -> Vector3<f64> {
    Vector3::new(p.z, -p.x, -p.y) + m.t
}

/// Robot-frame point → camera frame (A1, no tilt).
fn robot_to_cam(p: &Vector3<f64>, m: &CameraMount) -> Vector3<f64> {
    let q = p - m.t;
    Vector3::new(-q.y, -q.z, q.x)
}

impl RgbdPersonTracker {
    /// A tracker with a validated configuration.
    ///
    /// # Errors
    /// [`RgbdError::Config`] for invalid parameters.
    pub fn new(cfg: RgbdPersonConfig) -> Result<Self, RgbdError> {
        cfg.validate()?;
        Ok(Self {
            cfg,
            model: None,
            ekf: None,
            base: (0.0, 0.0),
            size: (0.0, 0.0),
            z0: 1.0,
            z_ref: 1.0,
            prev: (0.0, 0.0),
            state: OcclusionState::Normal,
            full_count: 0,
            last_t: TimeUs(0),
            force_off: false,
        })
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &RgbdPersonConfig {
        &self.cfg
    }

    /// The appearance model (template), after `init`.
    #[must_use]
    pub fn template(&self) -> Option<&PatchMultiCueModel> {
        self.model.as_ref()
    }

    /// Test hook (spec S6): while on, the detector reports "no detection".
    pub fn force_no_detection(&mut self, on: bool) {
        self.force_off = on;
    }

    /// Projects a robot-frame point to the image (`None` when Z ≤ 0.1 m).
    #[must_use]
    pub fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        let c = robot_to_cam(p, &self.cfg.mount);
        if c.z <= 0.1 {
            return None;
        }
        self.cfg.intrinsics.project(&c)
    }

    /// Back-projects pixel `(u, v)` at camera depth `z` into the robot frame.
    #[must_use]
    pub fn back_project(&self, u: f64, v: f64, z: f64) -> Vector3<f64> {
        cam_to_robot(&self.cfg.intrinsics.back_project(u, v, z), &self.cfg.mount)
    }

    fn check_frame(&self, f: &RgbdFrame) -> Result<(), RgbdError> {
        let k = &self.cfg.intrinsics;
        if (f.width, f.height) != (k.width, k.height) {
            return Err(RgbdError::State(format!(
                "frame is {}x{} but the intrinsics are for {}x{}",
                f.width, f.height, k.width, k.height
            )));
        }
        if f.depth_m.dimensions() != (f.width, f.height)
            || f.rgb.len() != 3 * f.width as usize * f.height as usize
        {
            return Err(VisionError::SizeMismatch {
                what: "depth vs RGB",
                a: f.depth_m.dimensions(),
                b: (f.width, f.height),
            }
            .into());
        }
        Ok(())
    }

    fn features(&self, f: &RgbdFrame, boxes: &[BBox]) -> Result<RgbdFeatures, RgbdError> {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for b in boxes {
            x0 = x0.min(b.left() - 1.0);
            y0 = y0.min(b.top() - 1.0);
            x1 = x1.max(b.right() + 2.0);
            y1 = y1.max(b.bottom() + 2.0);
        }
        let (w, h) = (f64::from(f.width), f64::from(f.height));
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let roi = (
            x0.clamp(0.0, w) as u32,
            y0.clamp(0.0, h) as u32,
            x1.clamp(0.0, w) as u32,
            y1.clamp(0.0, h) as u32,
        );
        let roi = if roi.0 >= roi.2 || roi.1 >= roi.3 {
            (0, 0, 1.min(f.width), 1.min(f.height))
        } else {
            roi
        };
        Ok(RgbdFeatures::new(
            f.width,
            f.height,
            &f.rgb,
            &f.depth_m,
            Some(roi),
            &self.cfg.model,
        )?)
    }

    fn dispatch_init(&mut self, stamp: Stamp, f: &RgbdFrame, bbox: BBox) -> Result<(), RgbdError> {
        self.check_frame(f)?;
        if !(bbox.is_valid() && bbox.w >= 1.0 && bbox.h >= 1.0) {
            return Err(RgbdError::State(format!(
                "init box {bbox:?} is empty or not finite"
            )));
        }
        let (iw, ih) = (f64::from(f.width), f64::from(f.height));
        if bbox.right() <= 0.0 || bbox.bottom() <= 0.0 || bbox.left() >= iw || bbox.top() >= ih {
            return Err(RgbdError::State(format!(
                "init box {bbox:?} lies outside the {}x{} image",
                f.width, f.height
            )));
        }
        let b0 = bbox.scale_about_centre(self.cfg.c_base);
        let n4 = 4.0 * f64::from(self.cfg.model.n);
        if b0.w < n4 || b0.h < n4 {
            return Err(RgbdError::State(format!(
                "init box too small: {}x{} after c_base (need ≥ {n4} px a side)",
                b0.w, b0.h
            )));
        }
        let feats = self.features(f, &[bbox])?;
        let model = PatchMultiCueModel::new(self.cfg.model, &feats, &bbox, &b0)?;
        let z0 = f64::from(model.z0());
        let y0 = self.back_project(b0.cx, b0.cy, z0);
        let (sp, sv) = (self.cfg.sigma_p.powi(2), self.cfg.sigma_v0.powi(2));
        let p0 = SMatrix::<f64, 5, 5>::from_diagonal(&SVector::<f64, 5>::from_column_slice(&[
            sp, sp, sp, sv, sv,
        ]));
        let x0 = SVector::<f64, 5>::from_column_slice(&[y0.x, y0.y, y0.z, 0.0, 0.0]);
        let mut motion = EgoCvModel::new(self.cfg.sigma_w, self.cfg.sigma_h)?;
        if self.cfg.paper_literal_11 {
            motion = motion.with_variant(EgoModel::PaperLiteral);
        }
        let meas = Position3::new(Matrix3::identity() * self.cfg.sigma_p.powi(2))?;
        self.ekf = Some(Ekf::new(Gaussian::try_new(x0, p0)?, motion, meas)?);
        self.model = Some(model);
        self.base = (b0.w, b0.h);
        self.size = (b0.w, b0.h);
        self.z0 = z0;
        self.z_ref = z0;
        self.prev = (b0.cx, b0.cy);
        self.state = OcclusionState::Normal;
        self.full_count = 0;
        self.last_t = stamp.t;
        Ok(())
    }

    fn candidates(&self, pred: Option<(f64, f64)>) -> Vec<BBox> {
        let (w, h) = self.size;
        let growth = (1.0 + 0.25 * f64::from(self.full_count)).min(3.0);
        let s = (w / 8.0).round().max(2.0) * growth;
        let mut out: Vec<BBox> = Vec::with_capacity(64);
        let mut seen: Vec<(i64, i64)> = Vec::with_capacity(64);
        let mut push = |cx: f64, cy: f64| {
            #[allow(clippy::cast_possible_truncation)]
            let key = (cx.round() as i64, cy.round() as i64);
            if !seen.contains(&key) && cx.is_finite() && cy.is_finite() {
                seen.push(key);
                out.push(BBox { cx, cy, w, h });
            }
        };
        let g = &self.cfg;
        for j in -g.grid_j..=g.grid_j {
            for i in -g.grid_i..=g.grid_i {
                push(
                    self.prev.0 + f64::from(i) * s,
                    self.prev.1 + f64::from(j) * s,
                );
            }
        }
        if g.mekf_candidate
            && let Some((u, v)) = pred
        {
            push(u, v);
            if g.mekf_local_grid {
                for j in -1..=1 {
                    for i in -1..=1 {
                        push(u + f64::from(i) * s, v + f64::from(j) * s);
                    }
                }
            }
        }
        out
    }

    #[allow(clippy::too_many_lines)]
    fn dispatch_step(&mut self, stamp: Stamp, f: &RgbdFrame) -> Result<TrackOutput, RgbdError> {
        self.check_frame(f)?;
        if self.model.is_none() || self.ekf.is_none() {
            return Err(RgbdError::State("step before init".into()));
        }
        let dt = stamp.t.secs_since(self.last_t);
        if !(dt.is_finite() && dt > 0.0) {
            return Err(RgbdError::State(format!(
                "timestamps must increase (dt = {dt} s)"
            )));
        }
        let cfg = self.cfg.clone();
        let delta = if cfg.ego {
            f.ego.delta(dt)
        } else {
            Pose2::identity()
        };
        let (xp, pp) = {
            let ekf = self
                .ekf
                .as_mut()
                .ok_or_else(|| RgbdError::State("no MEKF".into()))?;
            ekf.predict(&delta, dt)?;
            (*ekf.mean(), *ekf.cov())
        };
        self.last_t = stamp.t;
        let pred_pt = Vector3::new(xp[0], xp[1], xp[2]);
        let pred = self.project(&pred_pt);
        let z_pred = xp[0] - cfg.mount.t.x;
        let gz = cfg
            .gate_floor_m
            .max(cfg.gate_sigmas * pp[(0, 0)].max(0.0).sqrt());
        #[allow(clippy::cast_possible_truncation)]
        self.model
            .as_mut()
            .ok_or_else(|| RgbdError::State("no model".into()))?
            .set_depth_gate(Some((z_pred as f32, gz as f32)))?;
        let cands = self.candidates(pred);
        let feats = self.features(f, &cands)?;
        let model = self
            .model
            .as_mut()
            .ok_or_else(|| RgbdError::State("no model".into()))?;
        let mut described: Vec<(PatchDescriptor, CandidateScore)> = Vec::with_capacity(cands.len());
        for c in &cands {
            let d = model.describe_box(&feats, c)?;
            let s = model.score_descriptor(&d);
            described.push((d, s));
        }
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
        let all: Vec<usize> = (0..cands.len()).collect();
        let mut selection: Option<(usize, DetectionTier, CandidateScore, bool)> = None;
        if !self.force_off {
            if cfg.baseline {
                let items: Vec<(usize, f32)> = described
                    .iter()
                    .enumerate()
                    .map(|(i, x)| (i, x.1.s))
                    .collect();
                selection = pick(&items)
                    .map(|i| (i, DetectionTier::Overall, described[i].1.clone(), false));
            } else if let Some((i, t, s)) =
                tiers(&|i| Some((described[i].1.clone(), n_valid)), &all, 0)
            {
                selection = Some((i, t, s, false));
            } else {
                let t3_pool: Vec<usize> = all
                    .iter()
                    .copied()
                    .filter(|&i| {
                        let (d, s) = &described[i];
                        (s.d_flag || d.out_of_view)
                            && s.unoccluded.iter().filter(|&&u| u).count() >= k_min
                    })
                    .collect();
                let sub = |i: usize| {
                    let (d, s) = &described[i];
                    let n = s.unoccluded.iter().filter(|&&u| u).count();
                    Some((model.score_over(d, &s.unoccluded), n))
                };
                if let Some((i, t, s)) = tiers(&sub, &t3_pool, k_min) {
                    selection = Some((i, DetectionTier::Unoccluded(Box::new(t)), s, true));
                }
            }
        }
        // optional NIS gate
        let ekf = self
            .ekf
            .as_mut()
            .ok_or_else(|| RgbdError::State("no MEKF".into()))?;
        let meas_of = |i: usize| -> Option<Vector3<f64>> {
            let z = f64::from(described[i].0.z_star?);
            let b = cands[i];
            Some(cam_to_robot(
                &cfg.intrinsics.back_project(b.cx, b.cy, z),
                &cfg.mount,
            ))
        };
        if let (Some(g), Some((i, ..))) = (cfg.gate_chi2, selection.as_ref())
            && let Some(z) = meas_of(*i)
            && ekf.innovation(&z)?.nis > g
        {
            selection = None;
        }
        let mut out_state;
        let mut n_updated = 0;
        let (bbox, confirmed, tier, score, z_star);
        if let Some((i, tier_sel, s_sel, t3)) = selection {
            let (d, s_full) = &described[i];
            self.full_count = 0;
            out_state = if cfg.baseline {
                OcclusionState::Normal
            } else if t3 {
                if s_full.m >= cfg.severe_fraction {
                    OcclusionState::PartialOcclusion
                } else {
                    OcclusionState::SevereOcclusion
                }
            } else if s_full.d_flag {
                OcclusionState::PartialOcclusion
            } else if tier_sel == DetectionTier::Overall {
                OcclusionState::Normal
            } else {
                OcclusionState::AppearanceChange
            };
            if let Some(z) = meas_of(i) {
                ekf.update(&z)?;
            }
            let all_seen = !cfg.learn_unoccluded_only
                || model
                    .valid()
                    .iter()
                    .zip(&s_full.unoccluded)
                    .all(|(&v, &u)| !v || u);
            let learnable = (matches!(
                out_state,
                OcclusionState::Normal | OcclusionState::AppearanceChange
            ) && all_seen)
                || !cfg.occlusion_gate;
            let frac_ok = cfg.update_fraction.is_none_or(|u| s_full.m >= u);
            if learnable && frac_ok {
                n_updated = model.learn_counted(d, s_full);
            }
            let scale_ok = matches!(
                out_state,
                OcclusionState::Normal | OcclusionState::AppearanceChange
            );
            if scale_ok && let Some(z) = d.z_star {
                self.z_ref = f64::from(z);
            }
            let b = cands[i];
            self.prev = (b.cx, b.cy);
            bbox = Some(b);
            confirmed = true;
            tier = Some(tier_sel);
            score = Some(s_sel);
            z_star = d.z_star;
        } else {
            self.full_count += 1;
            out_state = if self.full_count > cfg.lost_after {
                OcclusionState::Lost
            } else {
                OcclusionState::FullOcclusion
            };
            let b = pred.map(|(u, v)| BBox {
                cx: u,
                cy: v,
                w: self.size.0,
                h: self.size.1,
            });
            if let Some(b) = b {
                self.prev = (b.cx, b.cy);
            }
            bbox = if out_state == OcclusionState::Lost {
                None
            } else {
                b
            };
            confirmed = false;
            tier = None;
            score = None;
            z_star = None;
        }
        if cfg.baseline {
            out_state = if confirmed {
                OcclusionState::Normal
            } else {
                out_state
            };
        }
        // scale for the next frame (A2)
        if cfg.scale_rule == ScaleRule::Disparity
            && matches!(
                out_state,
                OcclusionState::Normal | OcclusionState::AppearanceChange
            )
        {
            let target = self.z0 / self.z_ref;
            let (w0, h0) = self.base;
            let cur = self.size.0 / w0;
            let g = target.clamp(cur * (1.0 - cfg.scale_clamp), cur * (1.0 + cfg.scale_clamp));
            let min = 4.0 * f64::from(cfg.model.n);
            self.size = ((g * w0).max(min), (g * h0).max(min));
        }
        self.state = out_state;
        Ok(TrackOutput {
            stamp,
            bbox,
            confirmed,
            state: out_state,
            tier,
            score,
            z_star,
            gamma: cfg.c_base * self.size.0 / self.base.0,
            mean: *ekf.mean(),
            cov: *ekf.cov(),
            n_updated_patches: n_updated,
            predicted: pred,
            n_candidates: cands.len(),
        })
    }
}

impl SingleTargetTracker for RgbdPersonTracker {
    type Input = RgbdFrame;
    type Output = TrackOutput;
    type Error = RgbdError;

    fn init(&mut self, stamp: Stamp, input: &RgbdFrame, bbox: BBox) -> Result<(), RgbdError> {
        self.dispatch_init(stamp, input, bbox)
    }

    fn step(&mut self, stamp: Stamp, input: &RgbdFrame) -> Result<TrackOutput, RgbdError> {
        self.dispatch_step(stamp, input)
    }
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
) -> Result<Option<f64>, RgbdError> {
    let (bc, bt) = before.template();
    let (ac, at) = after.template();
    if bc.len() != ac.len() || bt.len() != at.len() || before.valid().len() != bc.len() {
        return Err(RgbdError::from(VisionError::from(CoreError::invalid(
            "template drift",
            format!(
                "templates of different grids ({} and {} patches)",
                bc.len(),
                ac.len()
            ),
        ))));
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for (k, &valid) in before.valid().iter().enumerate() {
        if !valid {
            continue;
        }
        for (b, a) in [(&bc[k], &ac[k]), (&bt[k], &at[k])] {
            if let (Some(b), Some(a)) = (b, a) {
                sum += f64::from(b.cosine(a).map_err(RgbdError::from)?);
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
/// A simulator or tracker error.
pub fn run_scenario(
    scene: &quarry_sim::rgbd::RgbdScene,
    seed: u64,
    cfg: &RgbdPersonConfig,
    odometry: OdometryFeed,
    on_frame: impl FnMut(&quarry_sim::rgbd::RgbdSample, &TrackOutput),
) -> Result<(ScenarioSummary, Vec<FrameRecord>), TrackerError> {
    run_scenario_frames(scene, seed, cfg, odometry, scene.len(), on_frame)
}

/// [`run_scenario`] over the first `n_frames` frames only (e.g. a quick demo).
///
/// # Errors
/// A simulator or tracker error.
pub fn run_scenario_frames(
    scene: &quarry_sim::rgbd::RgbdScene,
    seed: u64,
    cfg: &RgbdPersonConfig,
    odometry: OdometryFeed,
    n_frames: usize,
    mut on_frame: impl FnMut(&quarry_sim::rgbd::RgbdSample, &TrackOutput),
) -> Result<(ScenarioSummary, Vec<FrameRecord>), TrackerError> {
    let mut runs = run_scenario_multi(
        scene,
        seed,
        &[(cfg.clone(), odometry)],
        n_frames,
        |_, smp, o| on_frame(smp, o),
    )?;
    runs.pop()
        .ok_or_else(|| TrackerError::config("rgbd_person", "no run"))
}

/// Runs several trackers (configuration and odometry feed each) on the same scenario, rendering
/// each frame once: the result of each run is exactly that of [`run_scenario_frames`] with its
/// configuration (the trackers share nothing but the rendered frames). `on_frame` receives the
/// run's index.
///
/// # Errors
/// A simulator or tracker error.
#[allow(clippy::cast_precision_loss, clippy::too_many_lines)]
pub fn run_scenario_multi(
    scene: &quarry_sim::rgbd::RgbdScene,
    seed: u64,
    runs: &[(RgbdPersonConfig, OdometryFeed)],
    n_frames: usize,
    mut on_frame: impl FnMut(usize, &quarry_sim::rgbd::RgbdSample, &TrackOutput),
) -> Result<Vec<(ScenarioSummary, Vec<FrameRecord>)>, TrackerError> {
    let sim = |e: quarry_sim::SimError| TrackerError::config("rgbd_person", e.to_string());
    let vis_err = |e: VisionError| TrackerError::from(RgbdError::from(e));
    let mut trackers = runs
        .iter()
        .map(|(c, _)| RgbdPersonTracker::new(c.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let f0 = scene.render(0).map_err(sim)?;
    let init = f0
        .truth
        .amodal
        .ok_or_else(|| TrackerError::config("rgbd_person", "target not in view at frame 0"))?;
    let w = scene.intrinsics.width;
    let h = scene.intrinsics.height;
    let frame0 =
        RgbdFrame::new(w, h, f0.rgb, f0.depth_m, quarry_core::EgoMotion::None).map_err(vis_err)?;
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
        let smp = scene.render(k).map_err(sim)?;
        let t = &smp.truth;
        let mut fr = RgbdFrame::new(
            w,
            h,
            smp.rgb.clone(),
            smp.depth_m.clone(),
            quarry_core::EgoMotion::None,
        )
        .map_err(vis_err)?;
        for (r, ((_, odometry), tr)) in runs.iter().zip(trackers.iter_mut()).enumerate() {
            fr.ego = quarry_core::EgoMotion::Delta(match odometry {
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn config_presets_and_toml() {
        assert!(RgbdPersonConfig::paper().validate().is_ok());
        assert!(RgbdPersonConfig::strict().validate().is_ok());
        assert!(RgbdPersonConfig::whole_target_baseline().validate().is_ok());
        let c = RgbdPersonConfig::from_toml("c_base = 0.8\n[model]\nn = 3\n").unwrap();
        assert_eq!(c.model.n, 3);
        assert!((c.c_base - 0.8).abs() < 1e-12);
        assert!(RgbdPersonConfig::from_toml("c_base = -1").is_err());
        assert!(RgbdPersonConfig::from_toml("c_base = [").is_err());
        let back = toml::to_string(&RgbdPersonConfig::paper()).unwrap();
        assert_eq!(
            RgbdPersonConfig::from_toml(&back).unwrap(),
            RgbdPersonConfig::paper()
        );
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut t = RgbdPersonTracker::new(RgbdPersonConfig::paper()).unwrap();
        let rgb = vec![100u8; 640 * 480 * 3];
        let f = RgbdFrame::new(
            640,
            480,
            rgb.clone(),
            quarry_core::Plane::new(640, 480, 0.0),
            quarry_core::EgoMotion::None,
        )
        .unwrap();
        // step before init
        assert!(t.step(Stamp::from_frame(1, 0.1), &f).is_err());
        // all-zero depth
        let b = BBox::from_ltwh(300.0, 100.0, 80.0, 250.0);
        assert!(t.init(Stamp::from_frame(0, 0.1), &f, b).is_err());
        // zero-size / outside boxes
        let f2 = RgbdFrame::new(
            640,
            480,
            rgb,
            quarry_core::Plane::new(640, 480, 2.0),
            quarry_core::EgoMotion::None,
        )
        .unwrap();
        assert!(
            t.init(Stamp::from_frame(0, 0.1), &f2, BBox { w: 0.0, ..b })
                .is_err()
        );
        assert!(
            t.init(Stamp::from_frame(0, 0.1), &f2, BBox { cx: 5000.0, ..b })
                .is_err()
        );
        assert!(
            t.init(Stamp::from_frame(0, 0.1), &f2, BBox { cx: f64::NAN, ..b })
                .is_err()
        );
        // a small frame does not fit the intrinsics
        let small = RgbdFrame::new(
            32,
            32,
            vec![0; 32 * 32 * 3],
            quarry_core::Plane::new(32, 32, 2.0),
            quarry_core::EgoMotion::None,
        )
        .unwrap();
        assert!(t.init(Stamp::from_frame(0, 0.1), &small, b).is_err());
        // a valid init on a flat wall, then a non-increasing stamp
        t.init(Stamp::from_frame(0, 0.1), &f2, b).unwrap();
        assert!(t.step(Stamp::from_frame(0, 0.1), &f2).is_err());
        let o = t.step(Stamp::from_frame(1, 0.1), &f2).unwrap();
        // the MEKF candidate coincides with the G1 centre on a static target: deduplicated
        assert!((45..=54).contains(&o.n_candidates), "{}", o.n_candidates);
        // RGB / depth size mismatch is refused by the frame constructor
        assert!(
            RgbdFrame::new(
                640,
                480,
                vec![0; 10],
                quarry_core::Plane::new(640, 480, 2.0),
                quarry_core::EgoMotion::None
            )
            .is_err()
        );
        assert!(
            RgbdFrame::new(
                640,
                480,
                vec![0; 640 * 480 * 3],
                quarry_core::Plane::new(640, 479, 2.0),
                quarry_core::EgoMotion::None
            )
            .is_err()
        );
    }

    #[test]
    fn template_drift_is_one_for_an_unchanged_template_and_lower_for_another() {
        let frame = |rgb: Vec<u8>| {
            RgbdFrame::new(
                640,
                480,
                rgb,
                quarry_core::Plane::new(640, 480, 2.0),
                quarry_core::EgoMotion::None,
            )
            .unwrap()
        };
        // a colour-noise frame (seeded LCG) and a flat grey one, same box
        let mut x = 12_345u32;
        let noise: Vec<u8> = (0..640 * 480 * 3)
            .map(|_| {
                x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (x >> 24) as u8
            })
            .collect();
        let b = BBox::from_ltwh(300.0, 100.0, 80.0, 250.0);
        let model = |f: &RgbdFrame, cfg: RgbdPersonConfig| {
            let mut t = RgbdPersonTracker::new(cfg).unwrap();
            t.init(Stamp::from_frame(0, 0.1), f, b).unwrap();
            t.template().unwrap().clone()
        };
        let a = model(&frame(noise), RgbdPersonConfig::paper());
        let g = model(
            &frame(vec![100u8; 640 * 480 * 3]),
            RgbdPersonConfig::paper(),
        );
        let same = template_drift(&a, &a).unwrap().unwrap();
        assert!((same - 1.0).abs() < 1e-6, "{same}");
        let other = template_drift(&a, &g).unwrap().unwrap();
        assert!(other < 0.9, "{other}");
        // a template of another grid is refused
        let mut c = RgbdPersonConfig::paper();
        c.model.n = 3;
        let small = model(&frame(vec![100u8; 640 * 480 * 3]), c);
        assert!(template_drift(&a, &small).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// §6.1.12: projection and back-projection round-trip.
        #[test]
        fn projection_round_trip(u in 0.0f64..640.0, v in 0.0f64..480.0, z in 0.5f64..8.0) {
            let t = RgbdPersonTracker::new(RgbdPersonConfig::paper()).unwrap();
            let p = t.back_project(u, v, z);
            let (u2, v2) = t.project(&p).unwrap();
            prop_assert!((u - u2).abs() < 1e-9 && (v - v2).abs() < 1e-9);
            prop_assert!((p.x - z).abs() < 1e-12); // depth is the robot's x (t_x = 0)
        }
    }
}
