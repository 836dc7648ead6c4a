//! One particle (spec eq. (9)) and what it does at an observation epoch: the landmark updates
//! (FastSLAM 1.0), the target prediction, the gated likelihood matrix, the association and the
//! PDA update, and the particle's weight factor (spec §2.5–2.10).

use nalgebra::{DMatrix, Matrix2, Matrix3, Vector2, Vector3};
use quarry_assoc::{Jipda, Jpda, PaperLikelihood, weights_eq11};
use quarry_core::{
    Associator, Gaussian, InverseMeasurement, LandmarkId, LandmarkStore, LikelihoodMatrix, Pose2,
    TrackId, TrackPrior,
};
use quarry_filter::ekf::{self, MeasurementPrediction};
use quarry_filter::rbpf::fastslam2;
use quarry_filter::{RangeBearing, RangeBearingCv, UpdateForm};

use super::config::{AssociationMode, Proposal, SlamotConfig, TargetWeight};
use super::init::{InitPartner, two_point_state};
use crate::TrackerError;

/// One target slot inside a particle.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetSlot {
    /// Slot identity (common to all particles).
    pub id: TrackId,
    /// State (x, y, v_x, v_y).
    pub est: Gaussian<4>,
    /// Existence probability ψ (1 outside `Jipda`).
    pub existence: f64,
}

/// One particle (spec eq. (9)).
#[derive(Debug, Clone)]
pub struct SlamotParticle<S> {
    /// Robot pose sample.
    pub pose: Pose2,
    /// Landmark map (internal ids, see
    /// [`SlamotTracker::map_estimate`](super::SlamotTracker::map_estimate)).
    pub map: S,
    /// Target slots.
    pub targets: Vec<TargetSlot>,
    /// Log importance weight.
    pub log_w: f64,
}

pub(super) enum AssocImpl {
    Jpda(Jpda),
    Paper,
    Jipda(Jipda),
}

pub(super) struct EpochCtx<'a> {
    pub(super) cfg: &'a SlamotConfig,
    pub(super) r: Matrix2<f64>,
    pub(super) landmarks: &'a [(LandmarkId, Vector2<f64>, bool)],
    pub(super) targets: &'a [Vector2<f64>],
    pub(super) init_targets: bool,
    /// Detections that create the slots, with the previous-epoch partner (map frame) for
    /// two-point initiation.
    pub(super) init_sel: &'a [(usize, Option<InitPartner>)],
    pub(super) target_dt: f64,
    pub(super) cv: &'a super::config::TargetModel,
    pub(super) assoc: &'a AssocImpl,
    pub(super) jpda_for_weight: &'a Jpda,
    pub(super) gamma: f64,
}

pub(super) struct EpochOut {
    /// For each detection: Σ_l β_jl (how much the particle's targets explain it).
    pub(super) explained: Vec<f64>,
    /// β_jl (times ψ_l in `Jipda`), slots × detections.
    pub(super) beta: DMatrix<f64>,
    /// Σ of the normalised innovation squared ν'S⁻¹ν of this particle's landmark updates.
    pub(super) lm_nis: f64,
    /// Landmark updates (re-observations) this epoch.
    pub(super) lm_n: usize,
}

/// FastSLAM 2.0 (spec A20): conditions the particle's motion Gaussian (`p.pose`, `pose_cov`)
/// on the known-landmark detections in turn, draws the pose from the result and resets the
/// covariance. Returns the weight factor (the product of the predictive likelihoods; a gated
/// detection contributes the likelihood at d² = gate and does not condition the pose) and
/// (Σ NIS, count) of the predictive innovations.
fn measurement_proposal<S: LandmarkStore<Gaussian<2>>>(
    p: &mut SlamotParticle<S>,
    pose_cov: &mut Matrix3<f64>,
    rng: &mut dyn rand::RngCore,
    ctx: &EpochCtx<'_>,
) -> Result<(f64, f64, usize), TrackerError> {
    let mut mean = Vector3::new(p.pose.x, p.pose.y, p.pose.theta);
    let mut cov = *pose_cov;
    let (mut log_w, mut nis, mut n) = (0.0, 0.0, 0usize);
    for (id, z, is_new) in ctx.landmarks {
        if *is_new {
            continue;
        }
        let Some(lm) = p.map.get(*id) else { continue };
        let u = fastslam2::pose_update(&mean, &cov, lm, z, &ctx.r)?;
        nis += u.nis;
        n += 1;
        match ctx.cfg.landmark_gate {
            Some(g) if u.nis > g => log_w += u.log_likelihood_at(g),
            _ => {
                log_w += u.log_likelihood;
                mean = u.mean;
                cov = u.cov;
            }
        }
    }
    let x = fastslam2::sample_pose(&mean, &cov, rng);
    p.pose = Pose2::new(x.x, x.y, x.z);
    *pose_cov = Matrix3::zeros();
    Ok((log_w, nis, n))
}

pub(super) fn particle_epoch<S: LandmarkStore<Gaussian<2>>>(
    p: &mut SlamotParticle<S>,
    pose_cov: Option<&mut Matrix3<f64>>,
    rng: &mut dyn rand::RngCore,
    ctx: &EpochCtx<'_>,
) -> Result<EpochOut, TrackerError> {
    let cfg = ctx.cfg;
    // FastSLAM 2.0: the pose is drawn here, its weight factor replaces the landmark factor
    let proposal = match (cfg.proposal, pose_cov) {
        (Proposal::Measurement, Some(c)) => Some(measurement_proposal(p, c, rng, ctx)?),
        _ => None,
    };
    let rb = RangeBearing {
        sensor: p.pose,
        r: ctx.r,
    };
    let mut log_w = 0.0;
    let (mut lm_nis, mut lm_n) = (0.0, 0usize);
    // 5.1/5.2 landmarks (FastSLAM 1.0): weight before the update, new ones initialised.
    for (id, z, is_new) in ctx.landmarks {
        if *is_new {
            let g = rb.initialise(z)?;
            p.map.push(g);
        } else if let Some(lm) = p.map.get(*id) {
            let pred = MeasurementPrediction::new(lm, &rb)?;
            let nu = pred.innovation(&rb, z)?;
            let d2 = pred.nis(&nu);
            lm_nis += d2;
            lm_n += 1;
            match cfg.landmark_gate {
                Some(g) if d2 > g => log_w += pred.log_normaliser() - 0.5 * g,
                _ => {
                    log_w += pred.log_normaliser() - 0.5 * d2;
                    let post = pred.posterior(lm, &nu, UpdateForm::Joseph);
                    p.map.set(*id, post)?;
                }
            }
        }
    }
    if let Some((lw, nis, n)) = proposal {
        log_w = lw;
        lm_nis = nis;
        lm_n = n;
    }
    let nk = ctx.targets.len();
    let mut explained = vec![0.0; nk];
    let cvm = RangeBearingCv { point: rb };
    if ctx.init_targets {
        let mut beta = DMatrix::zeros(ctx.init_sel.len(), nk);
        for (l, (j, partner)) in ctx.init_sel.iter().enumerate() {
            let z = &ctx.targets[*j];
            let one = cvm.initialise_with_velocity(z, cfg.sigma_v0)?;
            let est = match partner {
                None => one,
                Some(prev) => {
                    let pos = Vector2::new(one.mean[0], one.mean[1]);
                    let cov = one.cov.fixed_view::<2, 2>(0, 0).into_owned();
                    two_point_state(pos, cov, prev, cfg.sigma_v0)?
                }
            };
            p.targets.push(TargetSlot {
                id: TrackId(l as u32 + 1),
                est,
                existence: 1.0,
            });
            explained[*j] = 1.0;
            beta[(l, *j)] = 1.0;
        }
        p.log_w += log_w;
        return Ok(EpochOut {
            explained,
            beta,
            lm_nis,
            lm_n,
        });
    }
    let n = p.targets.len();
    if n == 0 {
        p.log_w += log_w;
        return Ok(EpochOut {
            explained,
            beta: DMatrix::zeros(0, nk),
            lm_nis,
            lm_n,
        });
    }
    // 5.4 predict
    let jipda = matches!(ctx.assoc, AssocImpl::Jipda(_));
    for s in &mut p.targets {
        s.est = ekf::predict(&s.est, ctx.cv, &(), ctx.target_dt)?;
        if jipda {
            s.existence *= cfg.survival;
        }
    }
    // 5.5 predictions, innovations, likelihoods, gates
    let mut preds = Vec::with_capacity(n);
    let mut nus: Vec<Vec<Vector2<f64>>> = Vec::with_capacity(n);
    let mut ll = DMatrix::from_element(n, nk, f64::NEG_INFINITY);
    let mut ll_ungated = DMatrix::from_element(n, nk, f64::NEG_INFINITY);
    for (l, s) in p.targets.iter().enumerate() {
        let pred = MeasurementPrediction::new(&s.est, &cvm)?;
        let mut row = Vec::with_capacity(nk);
        for (j, z) in ctx.targets.iter().enumerate() {
            let nu = pred.innovation(&cvm, z)?;
            let d2 = pred.nis(&nu);
            let lg = pred.log_normaliser() - 0.5 * d2;
            ll_ungated[(l, j)] = lg;
            if d2 <= ctx.gamma {
                ll[(l, j)] = lg;
            }
            row.push(nu);
        }
        preds.push(pred);
        nus.push(row);
    }
    let lik = LikelihoodMatrix::new(ll)?;
    // 5.6 association and target weight
    let priors: Vec<TrackPrior> = p
        .targets
        .iter()
        .zip(&preds)
        .map(|(s, pred)| {
            let zh = pred.zhat;
            let outside =
                cfg.sensor_range.is_some_and(|r| zh[0] > r) || zh[1].abs() > 0.5 * cfg.sensor_fov;
            TrackPrior {
                existence: Some(s.existence),
                detection: outside.then_some(cfg.p_detect_outside),
            }
        })
        .collect();
    let a = match ctx.assoc {
        AssocImpl::Jpda(j) => j.associate(&lik, &priors)?,
        AssocImpl::Jipda(j) => j.associate(&lik, &priors)?,
        AssocImpl::Paper => PaperLikelihood.associate(&lik, &priors)?,
    };
    let eq11 = || -> Result<f64, TrackerError> {
        if nk == 0 {
            return Ok(0.0);
        }
        Ok(weights_eq11(&LikelihoodMatrix::new(ll_ungated.clone())?))
    };
    let log_wt = match (cfg.target_weight, cfg.association) {
        (TargetWeight::None, _) => 0.0,
        (TargetWeight::ModeDefault, AssociationMode::Paper) | (TargetWeight::PaperEq11, _) => {
            eq11()?
        }
        (TargetWeight::MarginalLikelihood, AssociationMode::Paper) => {
            ctx.jpda_for_weight.associate(&lik, &priors)?.log_normaliser
        }
        _ => a.log_normaliser,
    };
    // 5.7 PDA update
    for (l, s) in p.targets.iter_mut().enumerate() {
        let beta: Vec<f64> = a.beta.row(l).iter().copied().collect();
        s.est = quarry_filter::pda::update(&s.est, &preds[l], &nus[l], &beta)?;
        for j in 0..nk {
            explained[j] += beta[j + 1] * if jipda { s.existence } else { 1.0 };
        }
        if let Some(ex) = &a.existence {
            s.existence = ex[l];
        }
    }
    let mut beta = DMatrix::zeros(n, nk);
    for (l, s) in p.targets.iter().enumerate() {
        let e = if jipda { s.existence } else { 1.0 };
        for j in 0..nk {
            beta[(l, j)] = a.beta[(l, j + 1)] * e;
        }
    }
    if jipda {
        // explained in the unconditional sense: Σ_l ψ⁺_l β_jl
        for (j, e) in explained.iter_mut().enumerate() {
            *e = beta.column(j).sum();
        }
    }
    p.log_w += log_w + log_wt;
    Ok(EpochOut {
        explained,
        beta,
        lm_nis,
        lm_n,
    })
}
