//! The tracker: [`RgbdPersonTracker`] and its per-frame output [`TrackOutput`].
//!
//! Per frame (spec §2.11): MEKF predict with the odometry → depth gate and projected prediction
//! → candidate grid G1 around the previous output, the MEKF candidate and its local grid G2 →
//! features over the union of candidates → describe and score every candidate → tiered
//! selection (`select.rs`) → occlusion state (`occlusion.rs`) → MEKF update, template update
//! (eq. 12) and scale (A2) only in the states that allow it. With no detection the projected
//! prediction is the output (`FullOcclusion`, then `Lost` after `lost_after` frames).

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use quarry_core::{
    BBox, CameraMount, Gaussian, Pose2, SingleTargetTracker, Stamp, StateEstimate, StateLayout,
    TimeUs, TrackId, TrackReport, TrackStatus,
};
use quarry_filter::{EgoCvModel, EgoModel, Ekf, Position3};
use quarry_vision::VisionError;
use quarry_vision::multicue::{
    CandidateScore, PatchDescriptor, PatchMultiCueModel, RgbdFeatures, RgbdFrame,
};

use super::occlusion::{self, OcclusionState};
use super::select::{self, DetectionTier};
use super::{RgbdPersonConfig, ScaleRule};
use crate::{TrackerConfig, TrackerError};

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
    /// [`TrackerError::Config`] (or [`TrackerError::Vision`] for the appearance model's
    /// parameters) for invalid parameters.
    pub fn new(cfg: RgbdPersonConfig) -> Result<Self, TrackerError> {
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

    fn check_frame(&self, f: &RgbdFrame) -> Result<(), TrackerError> {
        let k = &self.cfg.intrinsics;
        if (f.width, f.height) != (k.width, k.height) {
            return Err(TrackerError::State(format!(
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

    fn features(&self, f: &RgbdFrame, boxes: &[BBox]) -> Result<RgbdFeatures, TrackerError> {
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

    fn dispatch_init(
        &mut self,
        stamp: Stamp,
        f: &RgbdFrame,
        bbox: BBox,
    ) -> Result<(), TrackerError> {
        self.check_frame(f)?;
        if !(bbox.is_valid() && bbox.w >= 1.0 && bbox.h >= 1.0) {
            return Err(TrackerError::State(format!(
                "init box {bbox:?} is empty or not finite"
            )));
        }
        let (iw, ih) = (f64::from(f.width), f64::from(f.height));
        if bbox.right() <= 0.0 || bbox.bottom() <= 0.0 || bbox.left() >= iw || bbox.top() >= ih {
            return Err(TrackerError::State(format!(
                "init box {bbox:?} lies outside the {}x{} image",
                f.width, f.height
            )));
        }
        let b0 = bbox.scale_about_centre(self.cfg.c_base);
        let n4 = 4.0 * f64::from(self.cfg.model.n);
        if b0.w < n4 || b0.h < n4 {
            return Err(TrackerError::State(format!(
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
    fn dispatch_step(&mut self, stamp: Stamp, f: &RgbdFrame) -> Result<TrackOutput, TrackerError> {
        self.check_frame(f)?;
        if self.model.is_none() || self.ekf.is_none() {
            return Err(TrackerError::State("step before init".into()));
        }
        let dt = stamp.t.secs_since(self.last_t);
        if !(dt.is_finite() && dt > 0.0) {
            return Err(TrackerError::State(format!(
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
                .ok_or_else(|| TrackerError::State("no MEKF".into()))?;
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
            .ok_or_else(|| TrackerError::State("no model".into()))?
            .set_depth_gate(Some((z_pred as f32, gz as f32)))?;
        let cands = self.candidates(pred);
        let feats = self.features(f, &cands)?;
        let model = self
            .model
            .as_mut()
            .ok_or_else(|| TrackerError::State("no model".into()))?;
        let mut described: Vec<(PatchDescriptor, CandidateScore)> = Vec::with_capacity(cands.len());
        for c in &cands {
            let d = model.describe_box(&feats, c)?;
            let s = model.score_descriptor(&d);
            described.push((d, s));
        }
        let mut selection = if self.force_off {
            None
        } else {
            select::select(&cfg, model, &cands, &described, pred)
        };
        // optional NIS gate
        let ekf = self
            .ekf
            .as_mut()
            .ok_or_else(|| TrackerError::State("no MEKF".into()))?;
        let meas_of = |i: usize| -> Option<Vector3<f64>> {
            let z = f64::from(described[i].0.z_star?);
            let b = cands[i];
            Some(cam_to_robot(
                &cfg.intrinsics.back_project(b.cx, b.cy, z),
                &cfg.mount,
            ))
        };
        if let (Some(g), Some(sel)) = (cfg.gate_chi2, selection.as_ref())
            && let Some(z) = meas_of(sel.index)
            && ekf.innovation(&z)?.nis > g
        {
            selection = None;
        }
        let mut out_state;
        let mut n_updated = 0;
        let (bbox, confirmed, tier, score, z_star);
        if let Some(sel) = selection {
            let i = sel.index;
            let (d, s_full) = &described[i];
            self.full_count = 0;
            out_state = occlusion::detected(&cfg, &sel, s_full);
            if let Some(z) = meas_of(i) {
                ekf.update(&z)?;
            }
            if occlusion::may_learn(&cfg, out_state, model.valid(), s_full) {
                n_updated = model.learn_counted(d, s_full);
            }
            if out_state.is_unoccluded()
                && let Some(z) = d.z_star
            {
                self.z_ref = f64::from(z);
            }
            let b = cands[i];
            self.prev = (b.cx, b.cy);
            bbox = Some(b);
            confirmed = true;
            tier = Some(sel.tier);
            score = Some(sel.score);
            z_star = d.z_star;
        } else {
            self.full_count += 1;
            out_state = occlusion::undetected(self.full_count, cfg.lost_after);
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
        if cfg.scale_rule == ScaleRule::Disparity && out_state.is_unoccluded() {
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
    type Error = TrackerError;

    fn init(&mut self, stamp: Stamp, input: &RgbdFrame, bbox: BBox) -> Result<(), TrackerError> {
        self.dispatch_init(stamp, input, bbox)
    }

    fn step(&mut self, stamp: Stamp, input: &RgbdFrame) -> Result<TrackOutput, TrackerError> {
        self.dispatch_step(stamp, input)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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
