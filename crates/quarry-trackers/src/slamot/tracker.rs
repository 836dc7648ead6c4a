//! [`SlamotTracker`]: the particle set — motion sampling, the observation epoch over every
//! particle (in parallel with the `rayon` feature), normalisation, read-out, JIPDA track
//! management and resampling (spec §2.4–2.13).

use std::collections::HashMap;

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, SMatrix, Vector2, Vector3, Vector4};
use quarry_assoc::{Jipda, Jpda};
use quarry_core::rng::stream;
use quarry_core::{
    CoreError, Gaussian, InverseMeasurement, LandmarkId, LandmarkStore, MotionModel,
    MultiTargetTracker, Pose2, Resampler, SampledMotion, Stamp, StateEstimate, StateLayout,
    TrackFlags, TrackId, TrackReport, TrackStatus, wrap_angle,
};
use quarry_filter::{Bicycle, RangeBearing, RangeBearingCv, Unicycle};
use serde::{Deserialize, Serialize};

use super::config::{AssociationMode, Proposal, Readout, RobotMotion, SlamotConfig, TargetInit};
use super::init::{InitPartner, MapPoints, two_point_pairs};
use super::observation::SlamotObservation;
use super::particle::{AssocImpl, EpochCtx, EpochOut, SlamotParticle, TargetSlot, particle_epoch};
use crate::{TrackerConfig, TrackerError};

/// Per-epoch statistics of the filter.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct EpochStats {
    /// Effective sample size after the update.
    pub neff: f64,
    /// Whether the particles were resampled.
    pub resampled: bool,
    /// Slots born this epoch.
    pub births: usize,
    /// Slots deleted this epoch.
    pub deaths: usize,
    /// Landmark re-observations this epoch (each innovation is χ² with 2 degrees of freedom
    /// when the filter is consistent).
    pub landmark_updates: usize,
    /// Mean normalised innovation squared of those updates, averaged over particles with their
    /// weights before the update (NaN without a landmark update); its consistency band over
    /// `n` updates is the χ²_{2n} interval divided by `n`.
    pub landmark_nis: f64,
}

/// The SLAMOT tracker over landmark store `S`.
#[derive(Debug, Clone)]
pub struct SlamotTracker<S> {
    cfg: SlamotConfig,
    seed: u64,
    particles: Vec<SlamotParticle<S>>,
    /// `Proposal::Measurement`: each particle's motion covariance accumulated since its pose
    /// was last drawn (its `pose` is then the motion mean); empty with `Proposal::Motion`.
    pose_cov: Vec<Matrix3<f64>>,
    weights: Vec<f64>,
    /// external landmark id -> internal store id (global: every particle pushes in this order)
    lm_index: HashMap<LandmarkId, LandmarkId>,
    lm_external: Vec<LandmarkId>,
    step_k: u64,
    t: f64,
    last_target_t: Option<f64>,
    targets_initialised: bool,
    next_slot_id: u32,
    stats: EpochStats,
    epochs: u64,
    resamples: u64,
    pose_est: Pose2,
    target_est: Vec<(TrackId, Gaussian<4>, f64)>,
    last_explained: Vec<f64>,
    /// Set when an epoch failed after the particles began to change (they may no longer agree
    /// on their slots): every later step is refused with this (control step, reason).
    failed: Option<(u64, String)>,
    last_beta: DMatrix<f64>,
    last_beta_ids: Vec<TrackId>,
    /// Previous epoch's target detections in the map frame (two-point initiation): time, points.
    prev_target_pts: Option<(f64, MapPoints)>,
}

/// The default landmark store: quarry-filter's persistent Arc tree (O(1) particle copy,
/// O(log M) landmark update).
pub type DefaultStore = quarry_filter::store::PersistentStore<Gaussian<2>>;
/// The flat alternative (O(M) particle copy; faster for small maps).
pub type FlatStore = quarry_filter::store::VecStore<Gaussian<2>>;

impl SlamotTracker<DefaultStore> {
    /// A tracker with the persistent store; `initial` = the known initial pose (map frame),
    /// `seed` = the filter's random stream (independent of the simulator's).
    pub fn new(cfg: SlamotConfig, initial: Pose2, seed: u64) -> Result<Self, TrackerError> {
        Self::with_store(cfg, initial, seed)
    }
}

impl<S> SlamotTracker<S>
where
    S: LandmarkStore<Gaussian<2>> + FromIterator<Gaussian<2>> + Send + Sync,
{
    /// A tracker over any landmark store.
    pub fn with_store(cfg: SlamotConfig, initial: Pose2, seed: u64) -> Result<Self, TrackerError> {
        cfg.validate()?;
        if !initial.is_finite() {
            return Err(CoreError::NonFinite {
                what: "initial pose",
            }
            .into());
        }
        let n = cfg.particles;
        let particles = (0..n)
            .map(|_| SlamotParticle {
                pose: initial,
                map: std::iter::empty().collect(),
                targets: Vec::new(),
                log_w: -(n as f64).ln(),
            })
            .collect();
        let pose_cov = if cfg.proposal == Proposal::Measurement {
            vec![Matrix3::zeros(); n]
        } else {
            Vec::new()
        };
        Ok(Self {
            seed,
            particles,
            pose_cov,
            weights: vec![1.0 / n as f64; n],
            lm_index: HashMap::new(),
            lm_external: Vec::new(),
            step_k: 0,
            t: 0.0,
            last_target_t: None,
            targets_initialised: false,
            next_slot_id: 1,
            stats: EpochStats::default(),
            epochs: 0,
            resamples: 0,
            pose_est: initial,
            target_est: Vec::new(),
            last_explained: Vec::new(),
            failed: None,
            last_beta: DMatrix::zeros(0, 0),
            last_beta_ids: Vec::new(),
            prev_target_pts: None,
            cfg,
        })
    }

    /// A tracker that starts from a known landmark map (e.g. a previous session's), shared by
    /// every particle: the store is built once and cloned into each particle (O(1) per particle
    /// for the persistent tree, O(M) for the flat store). Detections of these landmark ids are
    /// then updates, not initialisations. Duplicate ids or non-finite / non-PD landmarks are
    /// errors.
    pub fn with_prior_map(
        cfg: SlamotConfig,
        initial: Pose2,
        seed: u64,
        landmarks: &[(LandmarkId, Gaussian<2>)],
    ) -> Result<Self, TrackerError> {
        let mut t = Self::with_store(cfg, initial, seed)?;
        let mut store: S = std::iter::empty().collect();
        for (ext, g) in landmarks {
            if !(g.mean.iter().chain(g.cov.iter()).all(|v| v.is_finite())) {
                return Err(CoreError::NonFinite {
                    what: "prior landmark",
                }
                .into());
            }
            Gaussian::try_new(g.mean, g.cov)?;
            if t.lm_index.contains_key(ext) {
                return Err(TrackerError::config(
                    SlamotConfig::NAME,
                    format!("prior map: landmark id {} given twice", ext.0),
                ));
            }
            let id = LandmarkId(t.lm_external.len() as u32);
            t.lm_index.insert(*ext, id);
            t.lm_external.push(*ext);
            store.push(*g);
        }
        for p in &mut t.particles {
            p.map = store.clone();
        }
        Ok(t)
    }

    /// The configuration.
    pub fn config(&self) -> &SlamotConfig {
        &self.cfg
    }

    /// The particles (for plotting).
    pub fn particles(&self) -> &[SlamotParticle<S>] {
        &self.particles
    }

    /// Normalised weights of the last epoch (before resampling).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Robot pose estimate of the last step.
    pub fn pose_estimate(&self) -> Pose2 {
        self.pose_est
    }

    /// Target estimates of the last epoch: (slot id, Gaussian, existence).
    pub fn target_estimates(&self) -> &[(TrackId, Gaussian<4>, f64)] {
        &self.target_est
    }

    /// Statistics of the last observation epoch.
    pub fn last_epoch(&self) -> EpochStats {
        self.stats
    }

    /// (observation epochs so far, epochs with resampling).
    pub fn resample_counts(&self) -> (u64, u64) {
        (self.epochs, self.resamples)
    }

    /// Target slots created so far (their ids are `1..=slots_created()`; with a known target
    /// count, `n_targets` once they are initialised).
    pub fn slots_created(&self) -> u32 {
        self.next_slot_id - 1
    }

    /// For each target detection of the last epoch: Σ_i w̄_i Σ_l β^i_jl.
    pub fn last_explained(&self) -> &[f64] {
        &self.last_explained
    }

    /// For each target detection of the last epoch: the slot that explains it with weighted
    /// probability Σ_i w̄_i β^i_jl ≥ 0.5, if any (before births of that epoch).
    pub fn last_assignment(&self) -> Vec<Option<TrackId>> {
        let ids = &self.last_beta_ids;
        (0..self.last_beta.ncols())
            .map(|j| {
                let col = self.last_beta.column(j);
                col.iter()
                    .enumerate()
                    .max_by(|a, b| a.1.total_cmp(b.1))
                    .filter(|(_, v)| **v >= 0.5)
                    .and_then(|(l, _)| ids.get(l).copied())
            })
            .collect()
    }

    /// Weighted-mean landmark map: (external id, mean position).
    pub fn map_estimate(&self) -> Vec<(LandmarkId, [f64; 2])> {
        let mut out = Vec::with_capacity(self.lm_external.len());
        for (k, ext) in self.lm_external.iter().enumerate() {
            let id = LandmarkId(k as u32);
            let mut m = Vector2::zeros();
            let mut wsum = 0.0;
            for (p, w) in self.particles.iter().zip(&self.weights) {
                if let Some(g) = p.map.get(id) {
                    m += g.mean * *w;
                    wsum += w;
                }
            }
            if wsum > 0.0 {
                m /= wsum;
                out.push((*ext, [m.x, m.y]));
            }
        }
        out
    }

    fn sample_motion(&mut self, obs: &SlamotObservation) -> Result<(), TrackerError> {
        let (v, g) = obs.odometry;
        let [sv, sg] = self.cfg.control_noise;
        let seed = self.seed;
        let k = self.step_k;
        let dt = obs.dt;
        enum M {
            B(Bicycle),
            U(Unicycle),
        }
        let model = match self.cfg.motion {
            RobotMotion::Bicycle { wheelbase } => M::B(Bicycle::new(
                wheelbase,
                Matrix2::new(sv * sv, 0.0, 0.0, sg * sg),
            )?),
            RobotMotion::Unicycle => M::U(Unicycle::new(sv, sg)?),
        };
        if self.cfg.proposal == Proposal::Measurement {
            // FastSLAM 2.0: propagate the mean and the linearised covariance; the pose is drawn
            // at the next epoch (particle_epoch)
            let prop = |(p, c): (&mut SlamotParticle<S>, &mut Matrix3<f64>)| {
                let x = Vector3::new(p.pose.x, p.pose.y, p.pose.theta);
                let (y, f, q) = match &model {
                    M::B(b) => (
                        b.transition(&x, &(v, g), dt),
                        b.jacobian(&x, &(v, g), dt),
                        b.process_noise(&x, &(v, g), dt),
                    ),
                    M::U(u) => (
                        u.transition(&x, &(v, g), dt),
                        u.jacobian(&x, &(v, g), dt),
                        u.process_noise(&x, &(v, g), dt),
                    ),
                };
                let pc = f * *c * f.transpose() + q;
                *c = (pc + pc.transpose()) * 0.5;
                p.pose = Pose2::new(y[0], y[1], wrap_angle(y[2]));
            };
            self.particles
                .iter_mut()
                .zip(self.pose_cov.iter_mut())
                .for_each(prop);
            return Ok(());
        }
        let f = |(i, p): (usize, &mut SlamotParticle<S>)| {
            let mut rng = stream(seed, &[k, i as u64]);
            let x = Vector3::new(p.pose.x, p.pose.y, p.pose.theta);
            let y = match &model {
                M::B(b) => b.sample(&x, &(v, g), dt, &mut rng),
                M::U(u) => u.sample(&x, &(v, g), dt, &mut rng),
            };
            p.pose = Pose2::new(y[0], y[1], wrap_angle(y[2]));
        };
        #[cfg(feature = "rayon")]
        {
            use rayon::prelude::*;
            self.particles.par_iter_mut().enumerate().for_each(f);
        }
        #[cfg(not(feature = "rayon"))]
        self.particles.iter_mut().enumerate().for_each(f);
        Ok(())
    }

    fn epoch(&mut self, obs: &SlamotObservation) -> Result<(), TrackerError> {
        obs.check_detections()?;
        self.epochs += 1;
        let cfg = self.cfg.clone();
        let [sr, sb] = cfg.meas_noise;
        let r = Matrix2::new(sr * sr, 0.0, 0.0, sb * sb);
        // landmark ids: global, every particle pushes new ones in the same order
        let mut lms = Vec::with_capacity(obs.landmark_obs.len());
        for (ext, z) in &obs.landmark_obs {
            let zv = Vector2::new(z[0], z[1]);
            if let Some(id) = self.lm_index.get(ext) {
                lms.push((*id, zv, false));
            } else {
                let id = LandmarkId(self.lm_external.len() as u32);
                self.lm_index.insert(*ext, id);
                self.lm_external.push(*ext);
                lms.push((id, zv, true));
            }
        }
        let targets: Vec<Vector2<f64>> = obs
            .target_obs
            .iter()
            .map(|z| Vector2::new(z[0], z[1]))
            .collect();
        let init_sel = if cfg.track_management || self.targets_initialised {
            Vec::new()
        } else {
            self.select_init(&targets, &r)?
        };
        let init_targets = !init_sel.is_empty();
        let target_dt = self.last_target_t.map_or(0.0, |t0| self.t - t0);
        let cv = cfg.target_model()?;
        let jpda = Jpda::new(cfg.p_detect, cfg.p_gate, cfg.clutter_density)?;
        let assoc = match cfg.association {
            AssociationMode::Jpda => AssocImpl::Jpda(jpda),
            AssociationMode::Paper => AssocImpl::Paper,
            AssociationMode::Jipda => {
                AssocImpl::Jipda(Jipda::new(cfg.p_detect, cfg.p_gate, cfg.clutter_density)?)
            }
        };
        let ctx = EpochCtx {
            cfg: &cfg,
            r,
            landmarks: &lms,
            targets: &targets,
            init_targets,
            init_sel: &init_sel,
            target_dt,
            cv: &cv,
            assoc: &assoc,
            jpda_for_weight: &jpda,
            gamma: cfg.gate_threshold(),
        };
        let (seed, k) = (self.seed, self.step_k);
        let measurement = cfg.proposal == Proposal::Measurement;
        let mut covs: Vec<Option<&mut Matrix3<f64>>> = if measurement {
            self.pose_cov.iter_mut().map(Some).collect()
        } else {
            (0..self.particles.len()).map(|_| None).collect()
        };
        let run = |(i, (p, c)): (
            usize,
            (&mut SlamotParticle<S>, &mut Option<&mut Matrix3<f64>>),
        )| {
            // a stream of its own (the motion streams are [k, i], resampling [k, MAX])
            let mut rng = stream(seed, &[k, i as u64, 0xF2]);
            particle_epoch(p, c.as_deref_mut(), &mut rng, &ctx)
        };
        #[cfg(feature = "rayon")]
        let outs: Vec<Result<EpochOut, TrackerError>> = {
            use rayon::prelude::*;
            self.particles
                .par_iter_mut()
                .zip(covs.par_iter_mut())
                .enumerate()
                .map(run)
                .collect()
        };
        #[cfg(not(feature = "rayon"))]
        let outs: Vec<Result<EpochOut, TrackerError>> = self
            .particles
            .iter_mut()
            .zip(covs.iter_mut())
            .enumerate()
            .map(run)
            .collect();
        drop(covs);
        let outs: Vec<EpochOut> = outs.into_iter().collect::<Result<_, _>>()?;
        if init_targets {
            self.targets_initialised = true;
            self.next_slot_id = cfg.n_targets as u32 + 1;
        }
        if self.targets_initialised || !self.particles[0].targets.is_empty() || init_targets {
            self.last_target_t = Some(self.t);
        }
        let lm_n = outs.first().map_or(0, |o| o.lm_n);
        let landmark_nis = if lm_n > 0 {
            outs.iter()
                .zip(&self.weights)
                .map(|(o, w)| w * o.lm_nis)
                .sum::<f64>()
                / lm_n as f64
        } else {
            f64::NAN
        };
        // 6. normalise
        let lw: Vec<f64> = self.particles.iter().map(|p| p.log_w).collect();
        let (w, _) = quarry_filter::particles::normalise_log(&lw)
            .map_err(|_| TrackerError::WeightsDegenerate { step: self.step_k })?;
        let neff = quarry_filter::particles::effective_sample_size(&w);
        // keep log weights bounded
        for (p, wi) in self.particles.iter_mut().zip(&w) {
            p.log_w = wi.ln();
        }
        self.weights = w;
        self.last_explained = (0..targets.len())
            .map(|j| {
                outs.iter()
                    .zip(&self.weights)
                    .map(|(o, w)| w * o.explained[j])
                    .sum()
            })
            .collect();
        let n_slots = outs.first().map_or(0, |o| o.beta.nrows());
        let mut lb = DMatrix::zeros(n_slots, targets.len());
        for (o, w) in outs.iter().zip(&self.weights) {
            if o.beta.nrows() == n_slots {
                lb += &o.beta * *w;
            }
        }
        self.last_beta = lb;
        self.last_beta_ids = self
            .particles
            .first()
            .map(|p| p.targets.iter().map(|t| t.id).collect())
            .unwrap_or_default();
        // 7. estimates
        self.read_out();
        // 8. track management
        let (births, deaths) = if cfg.track_management {
            self.manage_tracks(&targets)?
        } else {
            (0, 0)
        };
        // 9. resample
        let resampled = neff < cfg.neff_threshold * cfg.particles as f64;
        if resampled {
            self.resample()?;
        }
        self.stats = EpochStats {
            neff,
            resampled,
            births,
            deaths,
            landmark_updates: lm_n,
            landmark_nis,
        };
        Ok(())
    }

    /// Which detections create the slots this epoch (empty: not yet), spec §2.12 / A19.
    fn select_init(
        &mut self,
        targets: &[Vector2<f64>],
        r: &Matrix2<f64>,
    ) -> Result<Vec<(usize, Option<InitPartner>)>, TrackerError> {
        let n = self.cfg.n_targets;
        match self.cfg.target_init {
            TargetInit::FirstN => Ok(if targets.len() == n {
                (0..n).map(|j| (j, None)).collect()
            } else {
                Vec::new()
            }),
            TargetInit::TwoPoint { max_speed } => {
                // weighted-mean pose of the (already propagated) particles
                let (mut x, mut y, mut c, mut s) = (0.0, 0.0, 0.0, 0.0);
                for (p, wi) in self.particles.iter().zip(&self.weights) {
                    x += wi * p.pose.x;
                    y += wi * p.pose.y;
                    c += wi * p.pose.theta.cos();
                    s += wi * p.pose.theta.sin();
                }
                let rb = RangeBearing {
                    sensor: Pose2::new(x, y, s.atan2(c)),
                    r: *r,
                };
                let mut pts = Vec::with_capacity(targets.len());
                for z in targets {
                    let g = rb.initialise(z)?;
                    pts.push((g.mean, g.cov));
                }
                let mut sel = Vec::new();
                if let Some((t0, prev)) = &self.prev_target_pts {
                    let dt = self.t - t0;
                    if dt > 0.0 {
                        sel = two_point_pairs(&pts, prev, dt, max_speed)
                            .into_iter()
                            .map(|(j, i)| {
                                (
                                    j,
                                    Some(InitPartner {
                                        p: prev[i].0,
                                        cov: prev[i].1,
                                        dt,
                                    }),
                                )
                            })
                            .collect();
                    }
                }
                self.prev_target_pts = Some((self.t, pts));
                if sel.len() == n {
                    Ok(sel)
                } else {
                    Ok(Vec::new())
                }
            }
        }
    }

    fn resample(&mut self) -> Result<(), TrackerError> {
        self.resamples += 1;
        let n = self.particles.len();
        let mut rng = stream(self.seed, &[self.step_k, u64::MAX]);
        let anc = quarry_filter::particles::Stratified.ancestors(&self.weights, &mut rng)?;
        let new: Vec<SlamotParticle<S>> = anc
            .iter()
            .map(|&a| {
                let mut p = self.particles[a].clone();
                p.log_w = -(n as f64).ln();
                p
            })
            .collect();
        self.particles = new;
        self.weights = vec![1.0 / n as f64; n];
        Ok(())
    }

    fn manage_tracks(&mut self, targets: &[Vector2<f64>]) -> Result<(usize, usize), TrackerError> {
        let cfg = &self.cfg;
        // deaths
        let n_slots = self.particles.first().map_or(0, |p| p.targets.len());
        let mut keep = vec![true; n_slots];
        for (l, k) in keep.iter_mut().enumerate() {
            let psi: f64 = self
                .particles
                .iter()
                .zip(&self.weights)
                .map(|(p, w)| w * p.targets[l].existence)
                .sum();
            if psi < cfg.delete_existence {
                *k = false;
            }
        }
        if let Some(max_sigma) = cfg.delete_sigma {
            // the read-out (step 7) holds each slot's weighted position covariance
            for (k, (_, g, _)) in keep.iter_mut().zip(&self.target_est) {
                let (a, b, c) = (g.cov[(0, 0)], g.cov[(0, 1)], g.cov[(1, 1)]);
                let largest = 0.5 * (a + c) + (0.25 * (a - c) * (a - c) + b * b).sqrt();
                // a NaN spread (cannot happen with validated input) also deletes
                if largest.is_nan() || largest.sqrt() > max_sigma {
                    *k = false;
                }
            }
        }
        let deaths = keep.iter().filter(|k| !**k).count();
        if deaths > 0 {
            for p in &mut self.particles {
                let mut i = 0;
                p.targets.retain(|_| {
                    let r = keep[i];
                    i += 1;
                    r
                });
            }
        }
        // births from unexplained detections
        let mut births = 0;
        for (j, z) in targets.iter().enumerate() {
            let slots = self.particles.first().map_or(0, |p| p.targets.len());
            if slots >= cfg.max_slots {
                break;
            }
            if self.last_explained.get(j).copied().unwrap_or(0.0) >= 0.5 {
                continue;
            }
            let id = TrackId(self.next_slot_id);
            self.next_slot_id += 1;
            for p in &mut self.particles {
                let m = RangeBearingCv::new(p.pose, cfg.meas_noise[0], cfg.meas_noise[1])?;
                p.targets.push(TargetSlot {
                    id,
                    est: m.initialise_with_velocity(z, cfg.sigma_v0)?,
                    existence: cfg.birth_existence,
                });
            }
            births += 1;
        }
        if births + deaths > 0 {
            self.read_out();
        }
        if self.last_target_t.is_none() && births > 0 {
            self.last_target_t = Some(self.t);
        }
        Ok((births, deaths))
    }

    fn read_out(&mut self) {
        let w = &self.weights;
        match self.cfg.readout {
            Readout::BestParticle => {
                let best = w
                    .iter()
                    .enumerate()
                    .max_by(|a, b| a.1.total_cmp(b.1))
                    .map_or(0, |(i, _)| i);
                let p = &self.particles[best];
                self.pose_est = p.pose;
                self.target_est = p
                    .targets
                    .iter()
                    .map(|s| (s.id, s.est, s.existence))
                    .collect();
            }
            Readout::WeightedMean => {
                let (mut x, mut y, mut c, mut s) = (0.0, 0.0, 0.0, 0.0);
                for (p, wi) in self.particles.iter().zip(w) {
                    x += wi * p.pose.x;
                    y += wi * p.pose.y;
                    c += wi * p.pose.theta.cos();
                    s += wi * p.pose.theta.sin();
                }
                self.pose_est = Pose2::new(x, y, s.atan2(c));
                let n_slots = self.particles.first().map_or(0, |p| p.targets.len());
                let mut est = Vec::with_capacity(n_slots);
                for l in 0..n_slots {
                    let mut m = Vector4::zeros();
                    let mut psi = 0.0;
                    for (p, wi) in self.particles.iter().zip(w) {
                        m += p.targets[l].est.mean * *wi;
                        psi += wi * p.targets[l].existence;
                    }
                    let mut cov = SMatrix::<f64, 4, 4>::zeros();
                    for (p, wi) in self.particles.iter().zip(w) {
                        let d = p.targets[l].est.mean - m;
                        cov += (p.targets[l].est.cov + d * d.transpose()) * *wi;
                    }
                    est.push((
                        self.particles[0].targets[l].id,
                        Gaussian::new_unchecked(m, (cov + cov.transpose()) * 0.5),
                        // the weights sum to 1 only up to rounding: Σ w_i · 1 can be 1 + 2⁻⁵²
                        psi.clamp(0.0, 1.0),
                    ));
                }
                self.target_est = est;
            }
        }
    }

    fn reports(&self, stamp: Stamp) -> Vec<TrackReport> {
        let jipda = self.cfg.association == AssociationMode::Jipda;
        self.target_est
            .iter()
            .map(|(id, g, psi)| {
                let status = if !jipda || *psi >= self.cfg.confirm_existence {
                    TrackStatus::Confirmed
                } else {
                    TrackStatus::Tentative
                };
                let mut r = TrackReport::new(stamp, *id, status);
                r.state = Some(StateEstimate {
                    layout: StateLayout::XyVxVy,
                    mean: DVector::from_column_slice(g.mean.as_slice()),
                    cov: Some(DMatrix::from_column_slice(4, 4, g.cov.as_slice())),
                });
                r.existence = jipda.then_some(*psi);
                r.flags = TrackFlags::NONE;
                r
            })
            .collect()
    }

    fn do_step(
        &mut self,
        stamp: Stamp,
        obs: &SlamotObservation,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        if let Some((k, why)) = &self.failed {
            return Err(TrackerError::State(format!(
                "this tracker failed at control step {k} ({why}) and its particles may disagree; \
                 start a new one"
            )));
        }
        // the input checks come before anything moves: bad input leaves the tracker as it was
        obs.check_controls()?;
        if obs.observe {
            obs.check_detections()?;
        }
        self.step_k = stamp.frame.0;
        self.sample_motion(obs)?;
        self.t += obs.dt;
        let epoch = obs.observe && (!obs.landmark_obs.is_empty() || !obs.target_obs.is_empty());
        if epoch {
            if let Err(e) = self.epoch(obs) {
                self.failed = Some((self.step_k, e.to_string()));
                return Err(e);
            }
        } else {
            // pose read-out between epochs (weights unchanged)
            let (mut x, mut y, mut c, mut s) = (0.0, 0.0, 0.0, 0.0);
            for (p, wi) in self.particles.iter().zip(&self.weights) {
                x += wi * p.pose.x;
                y += wi * p.pose.y;
                c += wi * p.pose.theta.cos();
                s += wi * p.pose.theta.sin();
            }
            self.pose_est = Pose2::new(x, y, s.atan2(c));
        }
        Ok(self.reports(stamp))
    }
}

impl<S> MultiTargetTracker for SlamotTracker<S>
where
    S: LandmarkStore<Gaussian<2>> + FromIterator<Gaussian<2>> + Send + Sync,
{
    type Input = SlamotObservation;
    type Error = TrackerError;

    /// One control step (`stamp.frame` = control step k, used for the random streams).
    fn step(
        &mut self,
        stamp: Stamp,
        input: &SlamotObservation,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        self.do_step(stamp, input)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_not_panics() {
        let bad = SlamotConfig {
            particles: 0,
            ..SlamotConfig::default()
        };
        assert!(matches!(
            SlamotTracker::new(bad, Pose2::identity(), 0),
            Err(TrackerError::Config { .. })
        ));
        let mut t = SlamotTracker::new(SlamotConfig::default(), Pose2::identity(), 0).unwrap();
        let nan = SlamotObservation {
            dt: 0.025,
            odometry: (f64::NAN, 0.0),
            ..Default::default()
        };
        assert!(t.step(Stamp::from_frame(1, 0.025), &nan).is_err());
        let bad_z = SlamotObservation {
            dt: 0.025,
            odometry: (1.0, 0.0),
            observe: true,
            landmark_obs: vec![],
            target_obs: vec![[f64::NAN, 0.0]],
        };
        let poses = |t: &SlamotTracker<DefaultStore>| {
            t.particles().iter().map(|p| p.pose).collect::<Vec<_>>()
        };
        let before = poses(&t);
        assert!(t.step(Stamp::from_frame(2, 0.025), &bad_z).is_err());
        assert_eq!(poses(&t), before, "a rejected step moved the particles");
        // a zero range is no detection: an error naming it, and nothing moved
        let zero = SlamotObservation {
            target_obs: vec![[0.0, 0.1]],
            ..bad_z.clone()
        };
        let e = t.step(Stamp::from_frame(2, 0.025), &zero).unwrap_err();
        assert!(e.to_string().contains("range"), "{e}");
        assert_eq!(poses(&t), before, "a rejected step moved the particles");
        // the fuzzer's case (`slamot_tracker`): subnormal ranges made a covariance that is not
        // positive definite half-way through the particles, which then disagreed on their
        // slots and a later read-out indexed past one's end. Refused up front now, and the
        // tracker goes on.
        let subnormal = SlamotObservation {
            dt: 32.6,
            odometry: (8.0, 2.0e-317),
            observe: true,
            landmark_obs: vec![],
            target_obs: vec![[5.4e-312, 2.0], [1.7e-307, 2.8e180], [3.3e-317, 33.0]],
        };
        let e = t.step(Stamp::from_frame(3, 0.025), &subnormal).unwrap_err();
        assert!(e.to_string().contains("range"), "{e}");
        let fine = SlamotObservation {
            target_obs: vec![[2.0, 0.1], [3.0, -0.2], [4.0, 0.3]],
            ..subnormal
        };
        t.step(Stamp::from_frame(4, 0.025), &fine).unwrap();
        // (the Vec store's bit-identical results: quarry-repro's tests/slamot.rs)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
        /// Arbitrary short observation sequences (odd step lengths including 0, any odometry,
        /// detections at zero, negative, huge or odd ranges and any bearing, non-finite values
        /// now and then), with every preset: each step gives a result or an error, never a
        /// panic, and after an accepted step the estimates are finite, the existences in
        /// [0, 1] and the slot ids distinct.
        #[test]
        fn arbitrary_observations_never_panic(
            preset in 0usize..3,
            seed in 0u64..1000,
            steps in proptest::collection::vec(
                (
                    proptest::prop_oneof![proptest::strategy::Just(0.0f64), 1e-4f64..0.5, proptest::strategy::Just(5.0)],
                    (-5.0f64..5.0, -3.0f64..3.0),
                    proptest::bool::ANY,
                    proptest::collection::vec((0u32..6, -1.0f64..40.0, -7.0f64..7.0), 0..4),
                    proptest::collection::vec((-1.0f64..40.0, -7.0f64..7.0), 0..4),
                    0u8..40,
                ),
                1..25,
            ),
        ) {
            use crate::TrackerConfig;
            use proptest::prelude::*;
            use super::super::config::Preset;
            let p = [Preset::Paper, Preset::S1, Preset::Mrclam][preset];
            let cfg = SlamotConfig {
                particles: 6,
                ..SlamotConfig::preset(p)
            };
            let mut t = SlamotTracker::new(cfg, Pose2::identity(), seed).unwrap();
            for (k, (dt, odo, observe, lms, tgs, poison)) in steps.into_iter().enumerate() {
                let mut obs = SlamotObservation {
                    dt,
                    odometry: odo,
                    observe,
                    landmark_obs: lms.into_iter().map(|(i, r, b)| (LandmarkId(i), [r, b])).collect(),
                    target_obs: tgs.into_iter().map(|(r, b)| [r, b]).collect(),
                };
                // now and then a non-finite value somewhere
                match poison {
                    0 => obs.odometry.0 = f64::NAN,
                    1 => obs.dt = f64::INFINITY,
                    2 if !obs.target_obs.is_empty() => obs.target_obs[0][1] = f64::NAN,
                    3 if !obs.landmark_obs.is_empty() => obs.landmark_obs[0].1[0] = f64::INFINITY,
                    _ => {}
                }
                let stamp = Stamp::from_frame(k as u64 + 1, dt.clamp(0.0, 5.0));
                let Ok(reports) = t.step(stamp, &obs) else { continue };
                let pose = t.pose_estimate();
                prop_assert!(pose.x.is_finite() && pose.y.is_finite() && pose.theta.is_finite());
                let mut ids = std::collections::BTreeSet::new();
                for (id, g, psi) in t.target_estimates() {
                    prop_assert!(ids.insert(*id), "duplicate slot {id:?}");
                    prop_assert!((0.0..=1.0).contains(psi), "existence {psi}");
                    prop_assert!(g.mean.iter().all(|v| v.is_finite()));
                }
                prop_assert_eq!(reports.len(), t.target_estimates().len());
                for (_, m) in t.map_estimate() {
                    prop_assert!(m[0].is_finite() && m[1].is_finite());
                }
            }
        }
    }

    #[test]
    fn prior_map_is_shared_and_updated() {
        let g = |x: f64, y: f64| Gaussian::try_new(Vector2::new(x, y), Matrix2::identity() * 0.01);
        let prior: Vec<(LandmarkId, Gaussian<2>)> = (0..300)
            .map(|i| (LandmarkId(1000 + i), g(f64::from(i) * 0.1, 5.0).unwrap()))
            .collect();
        let cfg = SlamotConfig {
            particles: 8,
            ..SlamotConfig::default()
        };
        let mut t = SlamotTracker::<DefaultStore>::with_prior_map(
            cfg.clone(),
            Pose2::identity(),
            3,
            &prior,
        )
        .unwrap();
        let ps = t.particles();
        assert_eq!(ps[0].map.unshared_nodes(&ps[7].map), 0);
        assert_eq!(t.map_estimate().len(), 300);
        // a detection of a prior landmark is an update: the map does not grow
        let z = [5.0, std::f64::consts::FRAC_PI_2];
        let obs = SlamotObservation {
            dt: 0.025,
            odometry: (0.0, 0.0),
            observe: true,
            landmark_obs: vec![(LandmarkId(1000), z)],
            target_obs: vec![],
        };
        t.step(Stamp::from_frame(1, 0.025), &obs).unwrap();
        assert_eq!(t.map_estimate().len(), 300);
        let dup = vec![prior[0], prior[0]];
        assert!(matches!(
            SlamotTracker::<DefaultStore>::with_prior_map(cfg.clone(), Pose2::identity(), 3, &dup),
            Err(TrackerError::Config { .. })
        ));
        let nan = vec![(
            LandmarkId(1),
            Gaussian::new_unchecked(Vector2::new(f64::NAN, 0.0), Matrix2::identity()),
        )];
        assert!(
            SlamotTracker::<FlatStore>::with_prior_map(cfg, Pose2::identity(), 3, &nan).is_err()
        );
    }

    /// A unicycle driving an arc among three known landmarks with noisy motion and precise
    /// measurements: the FastSLAM 2.0 proposal keeps a larger sample size and a pose at least
    /// as good as FastSLAM 1.0's.
    fn arc_run(proposal: Proposal) -> (f64, f64) {
        let g = |x: f64, y: f64| Gaussian::try_new(Vector2::new(x, y), Matrix2::identity() * 1e-4);
        let lms = [(4.0, 3.0), (6.0, -2.0), (1.0, 5.0)];
        let prior: Vec<(LandmarkId, Gaussian<2>)> = lms
            .iter()
            .enumerate()
            .map(|(i, l)| (LandmarkId(i as u32), g(l.0, l.1).unwrap()))
            .collect();
        let cfg = SlamotConfig {
            particles: 50,
            motion: RobotMotion::Unicycle,
            control_noise: [0.3, 0.3],
            meas_noise: [0.02, 0.005],
            proposal,
            ..SlamotConfig::default()
        };
        let mut t =
            SlamotTracker::<DefaultStore>::with_prior_map(cfg, Pose2::identity(), 11, &prior)
                .unwrap();
        let (v, w, dt) = (1.0, 0.2, 0.05);
        let (mut neff, mut err, mut n) = (0.0, 0.0, 0.0);
        for k in 1..=80u64 {
            let tt = dt * k as f64;
            let th = w * tt;
            let truth = Pose2::new((v / w) * th.sin(), (v / w) * (1.0 - th.cos()), th);
            let observe = k % 4 == 0;
            let landmark_obs = if observe {
                lms.iter()
                    .enumerate()
                    .map(|(i, l)| {
                        let (dx, dy) = (l.0 - truth.x, l.1 - truth.y);
                        (
                            LandmarkId(i as u32),
                            [dx.hypot(dy), wrap_angle(dy.atan2(dx) - truth.theta)],
                        )
                    })
                    .collect()
            } else {
                Vec::new()
            };
            let obs = SlamotObservation {
                dt,
                odometry: (v, w),
                observe,
                landmark_obs,
                target_obs: vec![],
            };
            t.step(Stamp::from_frame(k, dt), &obs).unwrap();
            if observe {
                let p = t.pose_estimate();
                neff += t.last_epoch().neff;
                err += (p.x - truth.x).hypot(p.y - truth.y);
                n += 1.0;
                assert_eq!(t.last_epoch().landmark_updates, 3);
                assert!(t.last_epoch().landmark_nis.is_finite());
            }
        }
        (neff / n, err / n)
    }

    /// With `TargetWeight::None` the target detections change the targets but not the particle
    /// weights: a run with and without them gives the same poses and map; with the mode's own
    /// weight they differ.
    #[test]
    fn target_weight_none_keeps_targets_out_of_the_pose() {
        use super::super::config::TargetWeight;
        let run = |weight: TargetWeight, with_targets: bool| {
            let cfg = SlamotConfig {
                particles: 30,
                target_weight: weight,
                control_noise: [0.3, 0.3],
                ..SlamotConfig::mrclam()
            };
            let mut t = SlamotTracker::new(cfg, Pose2::identity(), 5).unwrap();
            let mut poses = Vec::new();
            for k in 1..=60u64 {
                let observe = k % 3 == 0;
                let obs = SlamotObservation {
                    dt: 0.05,
                    odometry: (0.5, 0.1),
                    observe,
                    landmark_obs: if observe {
                        vec![(LandmarkId(1), [3.0 - 0.02 * k as f64, 0.2])]
                    } else {
                        vec![]
                    },
                    target_obs: if observe && with_targets {
                        vec![[2.0, -0.1 + 0.001 * k as f64], [4.0, 0.3]]
                    } else {
                        vec![]
                    },
                };
                t.step(Stamp::from_frame(k, 0.05), &obs).unwrap();
                let p = t.pose_estimate();
                poses.push((p.x, p.y, p.theta));
            }
            (poses, t.map_estimate(), t.slots_created())
        };
        let (a, ma, _) = run(TargetWeight::None, false);
        let (b, mb, slots) = run(TargetWeight::None, true);
        assert!(slots > 0, "the targets were tracked");
        assert_eq!(a, b);
        assert_eq!(ma, mb);
        let (c, _, _) = run(TargetWeight::ModeDefault, true);
        assert_ne!(a, c, "with the target factor the targets move the pose");
    }

    /// A target out of view keeps its existence while its position spreads. With `delete_sigma`
    /// its track is deleted once the position σ passes the bound: soon with constant velocity
    /// (σ grows as Δ^1.5), much later with a mean-reverting velocity (σ grows about as σ_v Δ),
    /// and never without the rule.
    #[test]
    fn delete_sigma_removes_tracks_that_no_longer_localise() {
        use super::super::config::TargetMotion;
        let life = |target_motion: TargetMotion, delete_sigma: Option<f64>| -> Option<f64> {
            let cfg = SlamotConfig {
                particles: 10,
                target_motion,
                delete_sigma,
                ..SlamotConfig::mrclam()
            };
            let mut t = SlamotTracker::new(cfg, Pose2::identity(), 3).unwrap();
            let (dt, mut theta) = (0.1, 0.0);
            for k in 1..=3000u64 {
                let time = k as f64 * dt;
                // watch the target at (2, 0) for 5 s, then turn to face away from it
                let w = if time > 5.0 && time <= 5.0 + std::f64::consts::PI {
                    1.0
                } else {
                    0.0
                };
                theta += w * dt;
                let obs = SlamotObservation {
                    dt,
                    odometry: (0.0, w),
                    observe: true,
                    landmark_obs: vec![(
                        LandmarkId(1),
                        [
                            3.0,
                            quarry_core::wrap_angle(std::f64::consts::FRAC_PI_2 - theta),
                        ],
                    )],
                    target_obs: if time <= 5.0 {
                        vec![[2.0, 0.0]]
                    } else {
                        vec![]
                    },
                };
                t.step(Stamp::from_frame(k, dt), &obs).unwrap();
                if time == 5.0 {
                    assert_eq!(t.target_estimates().len(), 1);
                    assert!(t.target_estimates()[0].2 > 0.9, "confirmed");
                }
                if time > 5.0 && t.target_estimates().is_empty() {
                    return Some(time);
                }
            }
            None
        };
        let cv = life(TargetMotion::Dwna, Some(1.0)).expect("deleted");
        let mr = TargetMotion::MeanReverting {
            sigma_v: 0.043,
            tau: 24.0,
        };
        let slow = life(mr, Some(1.0)).expect("deleted");
        eprintln!("deleted after {cv:.1} s (constant velocity), {slow:.1} s (mean-reverting)");
        assert!(cv < 15.0, "{cv}");
        assert!(slow > cv + 10.0, "{slow} vs {cv}");
        assert_eq!(
            life(TargetMotion::Dwna, None),
            None,
            "existence alone keeps it"
        );
    }

    #[test]
    fn measurement_proposal_keeps_more_particles_alive() {
        let (ess1, err1) = arc_run(Proposal::Motion);
        let (ess2, err2) = arc_run(Proposal::Measurement);
        eprintln!(
            "motion proposal: ESS {ess1:.1}, error {err1:.3}; measurement: ESS {ess2:.1}, error {err2:.3}"
        );
        assert!(ess2 > 1.5 * ess1, "{ess2} vs {ess1}");
        assert!(err2 <= err1 * 1.1 + 0.005, "{err2} vs {err1}");
        assert!(err2 < 0.05, "{err2}");
    }
}
