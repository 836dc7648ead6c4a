//! [`EkfSlamot`]: the joint state, its dense covariance and the control, landmark and target
//! steps (see the [module docs](super)).

use std::collections::HashMap;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use nalgebra::{DMatrix, DVector, Matrix2, Matrix2x3, SMatrix, Vector2, Vector3, Vector4};
use quarry_assoc::{Jipda, Jpda, PaperLikelihood};
use quarry_core::{
    Associator, CoreError, Gaussian, LandmarkId, LikelihoodMatrix, MotionModel, MultiTargetTracker,
    Pose2, Stamp, StateEstimate, StateLayout, TrackFlags, TrackId, TrackPrior, TrackReport,
    TrackStatus, wrap_angle,
};
use quarry_filter::{Bicycle, RangeBearing, Unicycle};

use crate::slamot::{
    AssociationMode, MapPoints, RobotMotion, SlamotConfig, SlamotObservation, TargetInit,
    two_point_pairs,
};
use crate::{TrackerConfig, TrackerError};

/// A point from the inverse model: mean, covariance from the sensor noise, `∂p/∂x_R`.
type PointInit = (Vector2<f64>, Matrix2<f64>, Matrix2x3<f64>);
/// A previous-epoch partner of a detection: mean, covariance, time since it [s].
type Partner = (Vector2<f64>, Matrix2<f64>, f64);

/// One target block of the joint state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TargetBlock {
    id: TrackId,
    /// Offset of (x, y, v_x, v_y) in the state.
    offset: usize,
    /// Existence ψ (1 outside `Jipda`).
    existence: f64,
}

/// The joint-EKF SLAMOT baseline (see the [module docs](super)).
#[derive(Debug, Clone)]
pub struct EkfSlamot {
    cfg: SlamotConfig,
    x: Vec<f64>,
    p: Mat<f64>,
    /// external landmark id → offset of its (x, y) in the state
    lm_offset: HashMap<LandmarkId, usize>,
    lm_order: Vec<LandmarkId>,
    targets: Vec<TargetBlock>,
    t: f64,
    last_target_t: Option<f64>,
    prev_target_pts: Option<(f64, MapPoints)>,
    epochs: u64,
}

/// Range, bearing, `H_x` (pose) and `H_p` (point) of the point at state offset `o`.
struct PointPrediction {
    zhat: Vector2<f64>,
    hx: Matrix2x3<f64>,
    hp: Matrix2<f64>,
    o: usize,
}

impl EkfSlamot {
    /// A filter at the known initial pose (zero covariance: it defines the map frame, as for the
    /// RBPF). `cfg` is the RBPF's configuration; the particle fields (`particles`, `resampler`,
    /// `readout`, `map_store`, `target_weight`) are ignored. Track management (births/deaths)
    /// is not supported: the target count must be known.
    pub fn new(cfg: SlamotConfig, initial: Pose2) -> Result<Self, TrackerError> {
        cfg.validate()?;
        if cfg.track_management {
            return Err(TrackerError::config(
                SlamotConfig::NAME,
                "the EKF-SLAMOT baseline needs a known target count (track_management = false)",
            ));
        }
        if !initial.is_finite() {
            return Err(CoreError::NonFinite {
                what: "initial pose",
            }
            .into());
        }
        Ok(Self {
            cfg,
            x: vec![initial.x, initial.y, initial.theta],
            p: Mat::zeros(3, 3),
            lm_offset: HashMap::new(),
            lm_order: Vec::new(),
            targets: Vec::new(),
            t: 0.0,
            last_target_t: None,
            prev_target_pts: None,
            epochs: 0,
        })
    }

    /// State dimension D = 3 + 2 M + 4 n.
    pub fn dim(&self) -> usize {
        self.x.len()
    }

    /// The joint covariance (D × D).
    pub fn covariance(&self) -> &Mat<f64> {
        &self.p
    }

    /// Robot pose estimate.
    pub fn pose_estimate(&self) -> Pose2 {
        Pose2::new(self.x[0], self.x[1], self.x[2])
    }

    /// Landmark estimates: (external id, position).
    pub fn map_estimate(&self) -> Vec<(LandmarkId, [f64; 2])> {
        self.lm_order
            .iter()
            .filter_map(|id| {
                self.lm_offset
                    .get(id)
                    .map(|&o| (*id, [self.x[o], self.x[o + 1]]))
            })
            .collect()
    }

    /// Target estimates: (slot id, marginal Gaussian, existence).
    pub fn target_estimates(&self) -> Vec<(TrackId, Gaussian<4>, f64)> {
        self.targets
            .iter()
            .map(|t| {
                let o = t.offset;
                let m = Vector4::new(self.x[o], self.x[o + 1], self.x[o + 2], self.x[o + 3]);
                let c = SMatrix::<f64, 4, 4>::from_fn(|i, j| self.p[(o + i, o + j)]);
                (
                    t.id,
                    Gaussian::new_unchecked(m, (c + c.transpose()) * 0.5),
                    t.existence,
                )
            })
            .collect()
    }

    fn r(&self) -> Matrix2<f64> {
        let [sr, sb] = self.cfg.meas_noise;
        Matrix2::new(sr * sr, 0.0, 0.0, sb * sb)
    }

    /// `P[off.., :] ← F P[off.., :]`, `P[:, off..] ← P[:, off..] Fᵀ`, `P[off.., off..] += Q`.
    fn transform_block(&mut self, off: usize, f: &DMatrix<f64>, q: &DMatrix<f64>) {
        let k = f.nrows();
        let d = self.dim();
        let fm = Mat::<f64>::from_fn(k, k, |i, j| f[(i, j)]);
        let rows = self.p.subrows(off, k).to_owned();
        matmul(
            self.p.subrows_mut(off, k),
            Accum::Replace,
            &fm,
            &rows,
            1.0,
            Par::Seq,
        );
        let cols = self.p.subcols(off, k).to_owned();
        matmul(
            self.p.subcols_mut(off, k),
            Accum::Replace,
            &cols,
            fm.transpose(),
            1.0,
            Par::Seq,
        );
        let _ = d;
        for i in 0..k {
            for j in 0..k {
                self.p[(off + i, off + j)] += q[(i, j)];
            }
        }
    }

    fn predict_robot(&mut self, u: (f64, f64), dt: f64) -> Result<(), TrackerError> {
        let [sv, sg] = self.cfg.control_noise;
        let x = Vector3::new(self.x[0], self.x[1], self.x[2]);
        let (xn, f, q) = match self.cfg.motion {
            RobotMotion::Bicycle { wheelbase } => {
                let m = Bicycle::new(wheelbase, Matrix2::new(sv * sv, 0.0, 0.0, sg * sg))?;
                (
                    m.transition(&x, &u, dt),
                    m.jacobian(&x, &u, dt),
                    m.process_noise(&x, &u, dt),
                )
            }
            RobotMotion::Unicycle => {
                let m = Unicycle::new(sv, sg)?;
                (
                    m.transition(&x, &u, dt),
                    m.jacobian(&x, &u, dt),
                    m.process_noise(&x, &u, dt),
                )
            }
        };
        self.x[0] = xn[0];
        self.x[1] = xn[1];
        self.x[2] = wrap_angle(xn[2]);
        let fd = DMatrix::from_fn(3, 3, |i, j| f[(i, j)]);
        let qd = DMatrix::from_fn(3, 3, |i, j| q[(i, j)]);
        self.transform_block(0, &fd, &qd);
        Ok(())
    }

    fn predict_point(&self, o: usize) -> Result<PointPrediction, TrackerError> {
        let rb = RangeBearing {
            sensor: self.pose_estimate(),
            r: self.r(),
        };
        let pt = Vector2::new(self.x[o], self.x[o + 1]);
        let dx = pt.x - self.x[0];
        let dy = pt.y - self.x[1];
        let q = dx * dx + dy * dy;
        if !(q.is_finite() && q > 0.0) {
            return Err(CoreError::invalid(
                "point",
                format!("at range {} from the robot (must be > 0)", q.sqrt()),
            )
            .into());
        }
        let r = q.sqrt();
        Ok(PointPrediction {
            zhat: Vector2::new(r, wrap_angle(dy.atan2(dx) - self.x[2])),
            hx: rb.pose_jacobian(&pt),
            hp: Matrix2::new(dx / r, dy / r, -dy / q, dx / q),
            o,
        })
    }

    /// `P Hᵀ` (D × 2) and `S = H P Hᵀ + R` for a prediction.
    fn pht_s(&self, pr: &PointPrediction) -> (Mat<f64>, Matrix2<f64>) {
        let d = self.dim();
        let hx = Mat::<f64>::from_fn(3, 2, |i, j| pr.hx[(j, i)]);
        let hp = Mat::<f64>::from_fn(2, 2, |i, j| pr.hp[(j, i)]);
        let mut pht = Mat::<f64>::zeros(d, 2);
        matmul(
            &mut pht,
            Accum::Replace,
            self.p.subcols(0, 3),
            &hx,
            1.0,
            Par::Seq,
        );
        matmul(
            &mut pht,
            Accum::Add,
            self.p.subcols(pr.o, 2),
            &hp,
            1.0,
            Par::Seq,
        );
        let mut s = self.r();
        for i in 0..2 {
            for j in 0..2 {
                let mut v = 0.0;
                for k in 0..3 {
                    v += pr.hx[(i, k)] * pht[(k, j)];
                }
                for k in 0..2 {
                    v += pr.hp[(i, k)] * pht[(pr.o + k, j)];
                }
                s[(i, j)] += v;
            }
        }
        (pht, (s + s.transpose()) * 0.5)
    }

    /// `x ← x + K ν̄`, `P ← P − K M Kᵀ`, `K = P Hᵀ S⁻¹` (M = S for a plain EKF update).
    fn apply(
        &mut self,
        pht: &Mat<f64>,
        s: &Matrix2<f64>,
        nu: &Vector2<f64>,
        m: &Matrix2<f64>,
    ) -> Result<(), TrackerError> {
        let si = s.try_inverse().ok_or(CoreError::NotPositiveDefinite {
            what: "EKF-SLAMOT innovation covariance",
        })?;
        let d = self.dim();
        let si_f = Mat::<f64>::from_fn(2, 2, |i, j| si[(i, j)]);
        let mut k = Mat::<f64>::zeros(d, 2);
        matmul(&mut k, Accum::Replace, pht, &si_f, 1.0, Par::Seq);
        for i in 0..d {
            self.x[i] += k[(i, 0)] * nu[0] + k[(i, 1)] * nu[1];
        }
        self.x[2] = wrap_angle(self.x[2]);
        let m_f = Mat::<f64>::from_fn(2, 2, |i, j| m[(i, j)]);
        let mut km = Mat::<f64>::zeros(d, 2);
        matmul(&mut km, Accum::Replace, &k, &m_f, 1.0, Par::Seq);
        matmul(&mut self.p, Accum::Add, &km, k.transpose(), -1.0, Par::Seq);
        if !self.x.iter().all(|v| v.is_finite()) {
            return Err(CoreError::NonFinite {
                what: "EKF-SLAMOT state after an update",
            }
            .into());
        }
        Ok(())
    }

    /// Appends a block of `k` states with mean `mean`, own covariance `own` (k × k, excluding the
    /// robot-induced part) and position Jacobian `gx` (2 × 3) w.r.t. the robot pose: the first
    /// two states are the point `g(x_R, z)`.
    fn augment(&mut self, mean: &[f64], own: &DMatrix<f64>, gx: &Matrix2x3<f64>) -> usize {
        let d = self.dim();
        let k = mean.len();
        let mut p = Mat::<f64>::zeros(d + k, d + k);
        p.submatrix_mut(0, 0, d, d).copy_from(&self.p);
        // cross: rows of the point = G_x P_R·
        for c in 0..d {
            for i in 0..2 {
                let v: f64 = (0..3).map(|a| gx[(i, a)] * self.p[(a, c)]).sum();
                p[(d + i, c)] = v;
                p[(c, d + i)] = v;
            }
        }
        for i in 0..k {
            for j in 0..k {
                let mut v = own[(i, j)];
                if i < 2 && j < 2 {
                    for a in 0..3 {
                        for b in 0..3 {
                            v += gx[(i, a)] * self.p[(a, b)] * gx[(j, b)];
                        }
                    }
                }
                p[(d + i, d + j)] = v;
            }
        }
        self.p = p;
        self.x.extend_from_slice(mean);
        d
    }

    fn inverse_point(&self, z: &Vector2<f64>) -> Result<PointInit, TrackerError> {
        if z[0] <= 0.0 {
            return Err(CoreError::invalid("range", format!("{} (must be > 0)", z[0])).into());
        }
        let th = self.x[2];
        let (s, c) = (th + z[1]).sin_cos();
        let pt = Vector2::new(self.x[0] + z[0] * c, self.x[1] + z[0] * s);
        let gz = Matrix2::new(c, -z[0] * s, s, z[0] * c);
        let gx = Matrix2x3::new(1.0, 0.0, -z[0] * s, 0.0, 1.0, z[0] * c);
        Ok((pt, gz * self.r() * gz.transpose(), gx))
    }

    fn symmetrise(&mut self) {
        let d = self.dim();
        for i in 0..d {
            for j in (i + 1)..d {
                let v = 0.5 * (self.p[(i, j)] + self.p[(j, i)]);
                self.p[(i, j)] = v;
                self.p[(j, i)] = v;
            }
        }
    }

    /// Which detections create the targets this epoch (same rule as the RBPF).
    fn select_init(
        &mut self,
        targets: &[Vector2<f64>],
    ) -> Result<Vec<(usize, Option<Partner>)>, TrackerError> {
        let n = self.cfg.n_targets;
        match self.cfg.target_init {
            TargetInit::FirstN => Ok(if targets.len() == n {
                (0..n).map(|j| (j, None)).collect()
            } else {
                Vec::new()
            }),
            TargetInit::TwoPoint { max_speed } => {
                let mut pts = Vec::with_capacity(targets.len());
                for z in targets {
                    let (p, c, _) = self.inverse_point(z)?;
                    pts.push((p, c));
                }
                let mut sel = Vec::new();
                if let Some((t0, prev)) = &self.prev_target_pts {
                    let dt = self.t - t0;
                    if dt > 0.0 {
                        sel = two_point_pairs(&pts, prev, dt, max_speed)
                            .into_iter()
                            .map(|(j, i)| (j, Some((prev[i].0, prev[i].1, dt))))
                            .collect();
                    }
                }
                self.prev_target_pts = Some((self.t, pts));
                Ok(if sel.len() == n { sel } else { Vec::new() })
            }
        }
    }

    fn epoch(&mut self, obs: &SlamotObservation) -> Result<(), TrackerError> {
        obs.check_detections()?;
        self.epochs += 1;
        let r = self.r();
        // landmarks: known ones updated sequentially, new ones appended
        for (id, z) in &obs.landmark_obs {
            let zv = Vector2::new(z[0], z[1]);
            if let Some(&o) = self.lm_offset.get(id) {
                let pr = self.predict_point(o)?;
                let (pht, s) = self.pht_s(&pr);
                let nu = Vector2::new(zv[0] - pr.zhat[0], wrap_angle(zv[1] - pr.zhat[1]));
                let d2 = s
                    .try_inverse()
                    .map_or(f64::INFINITY, |si| (nu.transpose() * si * nu)[0]);
                if self.cfg.landmark_gate.is_some_and(|g| d2 > g) {
                    continue;
                }
                self.apply(&pht, &s, &nu, &s)?;
            } else {
                let (pt, own, gx) = self.inverse_point(&zv)?;
                let own = DMatrix::from_fn(2, 2, |i, j| own[(i, j)]);
                let o = self.augment(&[pt.x, pt.y], &own, &gx);
                self.lm_offset.insert(*id, o);
                self.lm_order.push(*id);
            }
        }
        let dets: Vec<Vector2<f64>> = obs
            .target_obs
            .iter()
            .map(|z| Vector2::new(z[0], z[1]))
            .collect();
        if self.targets.is_empty() {
            let sel = self.select_init(&dets)?;
            for (l, (j, partner)) in sel.iter().enumerate() {
                let (pt, pc, gx) = self.inverse_point(&dets[*j])?;
                let sv = self.cfg.sigma_v0;
                let g = match partner {
                    None => {
                        let mut c = SMatrix::<f64, 4, 4>::zeros();
                        c.fixed_view_mut::<2, 2>(0, 0).copy_from(&pc);
                        c[(2, 2)] = sv * sv;
                        c[(3, 3)] = sv * sv;
                        Gaussian::try_new(Vector4::new(pt.x, pt.y, 0.0, 0.0), c)?
                    }
                    Some((pp, pcov, dt)) => {
                        crate::slamot::two_point_gaussian(pt, pc, *pp, *pcov, *dt, sv)?
                    }
                };
                let own = DMatrix::from_fn(4, 4, |i, j| g.cov[(i, j)]);
                let mean: Vec<f64> = g.mean.iter().copied().collect();
                let o = self.augment(&mean, &own, &gx);
                self.targets.push(TargetBlock {
                    id: TrackId(l as u32 + 1),
                    offset: o,
                    existence: 1.0,
                });
            }
            if !sel.is_empty() {
                self.last_target_t = Some(self.t);
            }
            self.symmetrise();
            return Ok(());
        }
        // targets: CV prediction over the elapsed time
        let dt = self.last_target_t.map_or(0.0, |t0| self.t - t0);
        self.last_target_t = Some(self.t);
        let cv = self.cfg.target_model()?;
        let jipda = self.cfg.association == AssociationMode::Jipda;
        let blocks = self.targets.clone();
        for b in &blocks {
            let o = b.offset;
            let s = Vector4::new(self.x[o], self.x[o + 1], self.x[o + 2], self.x[o + 3]);
            let f = cv.jacobian(&s, &(), dt);
            let q = cv.process_noise(&s, &(), dt);
            let sn = f * s;
            for i in 0..4 {
                self.x[o + i] = sn[i];
            }
            let fd = DMatrix::from_fn(4, 4, |i, j| f[(i, j)]);
            let qd = DMatrix::from_fn(4, 4, |i, j| q[(i, j)]);
            self.transform_block(o, &fd, &qd);
        }
        if jipda {
            for b in &mut self.targets {
                b.existence *= self.cfg.survival;
            }
        }
        // likelihoods from the joint prediction
        let n = self.targets.len();
        let nk = dets.len();
        let gamma = self.cfg.gate_threshold();
        let mut ll = DMatrix::from_element(n, nk, f64::NEG_INFINITY);
        let mut priors = Vec::with_capacity(n);
        for (l, b) in self.targets.iter().enumerate() {
            let pr = self.predict_point(b.offset)?;
            let (_, s) = self.pht_s(&pr);
            let si = s.try_inverse().ok_or(CoreError::NotPositiveDefinite {
                what: "EKF-SLAMOT target innovation covariance",
            })?;
            let det = s.determinant();
            if !(det.is_finite() && det > 0.0) {
                return Err(CoreError::NotPositiveDefinite {
                    what: "EKF-SLAMOT target innovation covariance",
                }
                .into());
            }
            let log_norm = -(2.0 * std::f64::consts::PI).ln() - 0.5 * det.ln();
            for (j, z) in dets.iter().enumerate() {
                let nu = Vector2::new(z[0] - pr.zhat[0], wrap_angle(z[1] - pr.zhat[1]));
                let d2 = (nu.transpose() * si * nu)[0];
                if d2 <= gamma {
                    ll[(l, j)] = log_norm - 0.5 * d2;
                }
            }
            let zh = pr.zhat;
            let outside = self.cfg.sensor_range.is_some_and(|rr| zh[0] > rr)
                || zh[1].abs() > 0.5 * self.cfg.sensor_fov;
            priors.push(TrackPrior {
                existence: Some(b.existence),
                detection: outside.then_some(self.cfg.p_detect_outside),
            });
        }
        let lik = LikelihoodMatrix::new(ll)?;
        let cfg = &self.cfg;
        let a = match cfg.association {
            AssociationMode::Jpda => Jpda::new(cfg.p_detect, cfg.p_gate, cfg.clutter_density)?
                .associate(&lik, &priors)?,
            AssociationMode::Jipda => Jipda::new(cfg.p_detect, cfg.p_gate, cfg.clutter_density)?
                .associate(&lik, &priors)?,
            AssociationMode::Paper => PaperLikelihood.associate(&lik, &priors)?,
        };
        // sequential PDA updates on the joint state
        for l in 0..n {
            let o = self.targets[l].offset;
            let b0 = a.beta[(l, 0)];
            if b0 >= 1.0 - 1e-15 {
                continue;
            }
            let pr = self.predict_point(o)?;
            let (pht, s) = self.pht_s(&pr);
            let mut nubar = Vector2::zeros();
            let mut spread = Matrix2::zeros();
            for (j, z) in dets.iter().enumerate() {
                let bj = a.beta[(l, j + 1)];
                if bj > 0.0 {
                    let nu = Vector2::new(z[0] - pr.zhat[0], wrap_angle(z[1] - pr.zhat[1]));
                    nubar += nu * bj;
                    spread += nu * nu.transpose() * bj;
                }
            }
            spread -= nubar * nubar.transpose();
            let m = s * (1.0 - b0) - spread;
            self.apply(&pht, &s, &nubar, &m)?;
        }
        if let Some(ex) = &a.existence {
            for (b, e) in self.targets.iter_mut().zip(ex) {
                b.existence = *e;
            }
        }
        self.symmetrise();
        let _ = r;
        Ok(())
    }

    fn reports(&self, stamp: Stamp) -> Vec<TrackReport> {
        let jipda = self.cfg.association == AssociationMode::Jipda;
        self.target_estimates()
            .into_iter()
            .map(|(id, g, psi)| {
                let status = if !jipda || psi >= self.cfg.confirm_existence {
                    TrackStatus::Confirmed
                } else {
                    TrackStatus::Tentative
                };
                let mut r = TrackReport::new(stamp, id, status);
                r.state = Some(StateEstimate {
                    layout: StateLayout::XyVxVy,
                    mean: DVector::from_column_slice(g.mean.as_slice()),
                    cov: Some(DMatrix::from_column_slice(4, 4, g.cov.as_slice())),
                });
                r.existence = jipda.then_some(psi);
                r.flags = TrackFlags::NONE;
                r
            })
            .collect()
    }
}

impl MultiTargetTracker for EkfSlamot {
    type Input = SlamotObservation;
    type Error = TrackerError;

    /// One control step: robot prediction, and at observation epochs the landmark and target
    /// updates.
    fn step(
        &mut self,
        stamp: Stamp,
        obs: &SlamotObservation,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        let (v, g) = obs.odometry;
        // the input checks come before anything moves: bad input leaves the filter as it was
        obs.check_controls()?;
        if obs.observe {
            obs.check_detections()?;
        }
        self.predict_robot((v, g), obs.dt)?;
        self.t += obs.dt;
        if obs.observe && (!obs.landmark_obs.is_empty() || !obs.target_obs.is_empty()) {
            self.epoch(obs)?;
        }
        Ok(self.reports(stamp))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::slamot::SlamotTracker;

    #[test]
    fn errors_not_panics() {
        let cfg = SlamotConfig {
            association: AssociationMode::Jipda,
            track_management: true,
            ..SlamotConfig::default()
        };
        assert!(matches!(
            EkfSlamot::new(cfg, Pose2::identity()),
            Err(TrackerError::Config { .. })
        ));
        assert!(EkfSlamot::new(SlamotConfig::default(), Pose2::new(f64::NAN, 0.0, 0.0)).is_err());
        let mut e = EkfSlamot::new(SlamotConfig::default(), Pose2::identity()).unwrap();
        let nan = SlamotObservation {
            dt: 0.025,
            odometry: (f64::NAN, 0.0),
            ..Default::default()
        };
        assert!(e.step(Stamp::from_frame(1, 0.025), &nan).is_err());
        let bad = SlamotObservation {
            dt: 0.025,
            odometry: (1.0, 0.0),
            observe: true,
            landmark_obs: vec![(LandmarkId(0), [f64::INFINITY, 0.0])],
            target_obs: vec![],
        };
        assert!(e.step(Stamp::from_frame(2, 0.025), &bad).is_err());
        let zero_range = SlamotObservation {
            dt: 0.025,
            odometry: (1.0, 0.0),
            observe: true,
            landmark_obs: vec![(LandmarkId(0), [0.0, 0.0])],
            target_obs: vec![],
        };
        assert!(e.step(Stamp::from_frame(3, 0.025), &zero_range).is_err());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Arbitrary observation streams (any floats, repeated/unknown ids, zero ranges, epochs
        /// with and without detections) give `Ok` or an error from both SLAMOT filters, never a
        /// panic, and an `Ok` state stays finite.
        #[test]
        fn arbitrary_input_never_panics(
            steps in proptest::collection::vec(
                (
                    proptest::prelude::any::<bool>(),
                    (-5.0f64..5.0, -1.0f64..1.0),
                    proptest::collection::vec((0u32..6, -1.0f64..40.0, -4.0f64..4.0), 0..5),
                    proptest::collection::vec((-1.0f64..40.0, -4.0f64..4.0), 0..5),
                    proptest::prelude::any::<u8>(),
                ),
                1..25,
            )
        ) {
            let cfg = SlamotConfig { particles: 4, ..SlamotConfig::s1() };
            let mut ekf = EkfSlamot::new(cfg.clone(), Pose2::identity()).unwrap();
            let mut pf = SlamotTracker::new(cfg, Pose2::identity(), 1).unwrap();
            let (mut ekf_ok, mut pf_ok) = (true, true);
            for (k, (observe, odo, lms, tgs, poison)) in steps.into_iter().enumerate() {
                let mut o = SlamotObservation {
                    dt: 0.025,
                    odometry: odo,
                    observe,
                    landmark_obs: lms.iter().map(|(i, r, b)| (LandmarkId(*i), [*r, *b])).collect(),
                    target_obs: tgs.iter().map(|(r, b)| [*r, *b]).collect(),
                };
                match poison % 8 {
                    0 => o.odometry.0 = f64::NAN,
                    1 => o.dt = f64::INFINITY,
                    2 => o.target_obs.push([f64::NAN, 0.0]),
                    _ => {}
                }
                let s = Stamp::from_frame(k as u64 + 1, 0.025);
                if ekf_ok {
                    match ekf.step(s, &o) {
                        Ok(_) => proptest::prop_assert!(ekf.pose_estimate().is_finite()),
                        Err(_) => ekf_ok = false,
                    }
                }
                if pf_ok {
                    match pf.step(s, &o) {
                        Ok(_) => proptest::prop_assert!(pf.pose_estimate().is_finite()),
                        Err(_) => pf_ok = false,
                    }
                }
            }
        }
    }
}
