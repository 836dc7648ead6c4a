//! The MRCLAM experiment: robot K of a UTIAS MRCLAM recording (read by `quarry_data::mrclam`)
//! does SLAM on the landmarks and tracks the other robots, scored against Vicon (robot, map and
//! per-robot errors, OSPA, association accuracy).

use std::collections::HashMap;

use quarry_core::{
    LandmarkId, MultiTargetTracker, Pose2, Stamp, TrackId, TrackReport, TrackStatus, wrap_angle,
};
use quarry_data::mrclam::MrclamRun;
use quarry_trackers::slamot::{DefaultStore, SlamotConfig, SlamotTracker, smooth_run};
use serde::{Deserialize, Serialize};

use super::score::{MapScore, TrajectoryScore, score_map, score_targets, score_trajectory};
use super::{mean_var, mrclam_observation};
use crate::Result;

/// One confirmed target track at one epoch (for the tracks CSV).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackRow {
    /// Epoch time \[s\] since the run's start.
    pub t: f64,
    /// Track (slot) id.
    pub id: TrackId,
    /// Mean (x, y, v_x, v_y).
    pub state: [f64; 4],
    /// JIPDA existence probability.
    pub existence: f64,
}

/// The result of one MRCLAM run (robot K does SLAM and tracks the other robots).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MrclamResult {
    /// Robot position error per observation epoch (against Vicon).
    pub robot_err: Vec<f64>,
    /// Epoch times \[s\].
    pub epoch_t: Vec<f64>,
    /// Mean landmark position error of the final map \[m\] over the landmarks seen.
    pub map_err: f64,
    /// Landmarks in the final map.
    pub landmarks_mapped: usize,
    /// Per target robot: position error series of the track mapped to it (majority vote of the
    /// detections it explained), at epochs where that track is confirmed.
    pub target_err: Vec<Vec<f64>>,
    /// Per target robot: the slot mapped to it (None = never tracked).
    pub target_slot: Vec<Option<TrackId>>,
    /// Mean OSPA (p = 2, c = 1 m) per epoch between confirmed tracks and the target robots
    /// currently within the sensor's range and field of view.
    pub ospa: f64,
    /// Fraction of target detections (of real robots) associated to a slot mapped to the robot
    /// that produced them; unassociated detections count as wrong.
    pub assoc_accuracy: f64,
    /// Per target robot: its detections and how many were associated correctly.
    pub assoc_per_target: Vec<(usize, usize)>,
    /// Detections of real robots that no slot explained (β < 0.5 everywhere: births and misses
    /// of the association), counted as wrong in [`Self::assoc_accuracy`].
    pub assoc_unassigned: usize,
    /// Slots ever created.
    pub slots_created: u32,
    /// Wall-clock milliseconds per control step.
    pub ms_per_step: f64,
    /// Estimated robot trajectory per epoch (x, y, θ).
    pub robot_est: Vec<[f64; 3]>,
    /// True robot trajectory per epoch.
    pub robot_true: Vec<[f64; 3]>,
    /// Final landmark map estimate.
    pub map: Vec<(LandmarkId, [f64; 2])>,
    /// Robot trajectory scores ([`score_trajectory`]: ATE with and without alignment).
    pub trajectory: TrajectoryScore,
    /// Final map scores ([`score_map`], aligned with the trajectory's transform).
    pub map_score: MapScore,
    /// Mean GOSPA (p = 2, c = 1 m, α = 2) over epochs, same sets as [`Self::ospa`].
    pub gospa: f64,
    /// Confirmed target tracks at every scored epoch.
    pub tracks: Vec<TrackRow>,
    /// Effective sample size after the update, per scored epoch (NaN where the epoch had no
    /// detection to process).
    pub neff: Vec<f64>,
    /// Whether the particles were resampled, per scored epoch.
    pub resampled: Vec<bool>,
    /// Weighted mean normalised innovation squared of the landmark updates, per scored epoch
    /// (NaN without a landmark update), with the number of landmark updates (each χ²₂).
    pub landmark_nis: Vec<(f64, usize)>,
    /// The filter's pose at every observation epoch (every frame with `observe`, with or
    /// without truth): the starting point of [`smooth_mrclam`].
    #[serde(skip)]
    pub epoch_pose: Vec<Pose2>,
}

/// A forward run refined by the batch smoother ([`smooth_run`]), scored like the filter.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MrclamSmoothed {
    /// Robot position error per scored epoch (the filter's epochs).
    pub robot_err: Vec<f64>,
    /// Smoothed robot trajectory per scored epoch (x, y, θ).
    pub robot_est: Vec<[f64; 3]>,
    /// Trajectory scores (as [`MrclamResult::trajectory`]).
    pub trajectory: TrajectoryScore,
    /// Mean landmark position error of the smoothed map \[m\].
    pub map_err: f64,
    /// Map scores (as [`MrclamResult::map_score`]).
    pub map_score: MapScore,
    /// Smoothed landmark map.
    pub map: Vec<(LandmarkId, [f64; 2])>,
    /// Estimated odometry calibration: speed scale, turn-rate scale, turn-rate bias \[rad/s\],
    /// time offset \[s\] (identity values when not estimated).
    pub calibration: [f64; 4],
    /// Accepted Levenberg–Marquardt steps.
    pub iterations: usize,
    /// Whether the solver converged before its iteration limit.
    pub converged: bool,
    /// Landmark detections down-weighted by the Huber loss at the end.
    pub downweighted: usize,
    /// Cost before and after.
    pub cost: (f64, f64),
    /// Wall-clock milliseconds of the smoothing.
    pub ms: f64,
}

/// Refines a forward run ([`run_mrclam`] on the same `run` and `cfg`) with the batch smoother,
/// starting from the filter's epoch poses and final map; `calibrate` also estimates the
/// odometry's calibration ([`quarry_trackers::slamot::smoother_config`]).
pub fn smooth_mrclam(
    cfg: &SlamotConfig,
    run: &MrclamRun,
    forward: &MrclamResult,
    calibrate: bool,
) -> Result<MrclamSmoothed> {
    let start = std::time::Instant::now();
    let obs: Vec<_> = run.frames.iter().map(mrclam_observation).collect();
    let s = smooth_run(
        cfg,
        run.initial_pose,
        &obs,
        Some(&forward.epoch_pose),
        &forward.map,
        calibrate,
    )?;
    let ms = 1e3 * start.elapsed().as_secs_f64();
    let mut robot_err = Vec::new();
    let mut robot_est = Vec::new();
    let mut robot_true = Vec::new();
    for (f, &node) in run.frames.iter().filter(|f| f.observe).zip(&s.epoch_nodes) {
        if let Some(tp) = f.truth.robot {
            let p = s.result.poses[node];
            robot_err.push((p.x - tp.x).hypot(p.y - tp.y));
            robot_est.push([p.x, p.y, p.theta]);
            robot_true.push([tp.x, tp.y, tp.theta]);
        }
    }
    let map = s.result.landmarks.clone();
    let trajectory = score_trajectory(&robot_est, &robot_true)?;
    let map_score = score_map(&map, &run.landmarks, trajectory.alignment);
    let c = s.result.calibration;
    Ok(MrclamSmoothed {
        robot_err,
        robot_est,
        trajectory,
        map_err: map_score.mean,
        map_score,
        map,
        calibration: [c.speed_scale, c.turn_scale, c.turn_bias, c.time_offset],
        iterations: s.result.iterations,
        converged: s.result.converged,
        downweighted: s.result.downweighted,
        cost: (s.result.initial_cost, s.result.final_cost),
        ms,
    })
}

/// The MRCLAM configuration ([`SlamotConfig::mrclam`], the `mrclam` preset) with `particles`
/// particles.
pub fn mrclam_config(particles: usize) -> SlamotConfig {
    SlamotConfig {
        particles,
        ..SlamotConfig::mrclam()
    }
}

/// Runs the tracker on an MRCLAM run and scores it against Vicon.
pub fn run_mrclam(cfg: &SlamotConfig, run: &MrclamRun, filter_seed: u64) -> Result<MrclamResult> {
    let mut tr =
        SlamotTracker::<DefaultStore>::with_store(cfg.clone(), run.initial_pose, filter_seed)?;
    let n_t = run.target_robots.len();
    let mut robot_err = Vec::new();
    let mut epoch_t = Vec::new();
    let mut robot_est = Vec::new();
    let mut robot_true = Vec::new();
    let mut tracks = Vec::new();
    let mut neff = Vec::new();
    let mut resampled = Vec::new();
    let mut landmark_nis = Vec::new();
    let mut epoch_pose = Vec::new();
    // (epoch, detection source, assigned slot)
    let mut assoc: Vec<(Option<usize>, Option<TrackId>)> = Vec::new();
    // per epoch: reports and truth
    type Epoch = (Vec<TrackReport>, Vec<Option<[f64; 2]>>, Pose2);
    let mut hist: Vec<Epoch> = Vec::new();
    let start = std::time::Instant::now();
    let mut last_slots = 0;
    for f in &run.frames {
        let reports = tr.step(Stamp::from_frame(f.k, f.dt), &mrclam_observation(f))?;
        if !f.observe {
            continue;
        }
        let p = tr.pose_estimate();
        epoch_pose.push(p);
        if let Some(tp) = f.truth.robot {
            robot_err.push((p.x - tp.x).hypot(p.y - tp.y));
            epoch_t.push(f.t);
            robot_est.push([p.x, p.y, p.theta]);
            robot_true.push([tp.x, tp.y, tp.theta]);
            let processed = !(f.landmark_obs.is_empty() && f.target_obs.is_empty());
            let st = tr.last_epoch();
            neff.push(if processed { st.neff } else { f64::NAN });
            resampled.push(processed && st.resampled);
            landmark_nis.push(if processed && st.landmark_updates > 0 {
                (st.landmark_nis, st.landmark_updates)
            } else {
                (f64::NAN, 0)
            });
            for r in &reports {
                if r.status != TrackStatus::Confirmed {
                    continue;
                }
                if let Some(s) = &r.state
                    && s.mean.len() >= 4
                {
                    tracks.push(TrackRow {
                        t: f.t,
                        id: r.id,
                        state: [s.mean[0], s.mean[1], s.mean[2], s.mean[3]],
                        existence: r.existence.unwrap_or(1.0),
                    });
                }
            }
        }
        if !f.target_obs.is_empty() {
            let a = tr.last_assignment();
            for (j, src) in f.truth.target_obs_source.iter().enumerate() {
                assoc.push((*src, a.get(j).copied().flatten()));
            }
        }
        last_slots = last_slots.max(tr.slots_created());
        if let Some(tp) = f.truth.robot {
            hist.push((reports, f.truth.targets.clone(), tp));
        }
    }
    let el = start.elapsed().as_secs_f64();
    // majority vote slot -> robot
    let mut votes: HashMap<TrackId, Vec<usize>> = HashMap::new();
    for (src, slot) in &assoc {
        if let (Some(s), Some(id)) = (src, slot) {
            votes.entry(*id).or_insert_with(|| vec![0; n_t])[*s] += 1;
        }
    }
    let slot_robot: HashMap<TrackId, usize> = votes
        .iter()
        .filter_map(|(id, v)| {
            v.iter()
                .enumerate()
                .max_by_key(|x| *x.1)
                .filter(|x| *x.1 > 0)
                .map(|(r, _)| (*id, r))
        })
        .collect();
    let mut per = vec![(0usize, 0usize); n_t];
    for (src, slot) in &assoc {
        if let Some(s) = src {
            per[*s].0 += 1;
            if slot.and_then(|id| slot_robot.get(&id)) == Some(s) {
                per[*s].1 += 1;
            }
        }
    }
    let unassigned = assoc
        .iter()
        .filter(|(src, slot)| src.is_some() && slot.is_none())
        .count();
    let tot: usize = per.iter().map(|p| p.0).sum();
    let ok: usize = per.iter().map(|p| p.1).sum();
    // target errors: every confirmed slot mapped to robot r contributes at each epoch
    let mut target_err = vec![Vec::new(); n_t];
    let mut target_slot = vec![None; n_t];
    for r in 0..n_t {
        // the slot with the most votes for r
        target_slot[r] = votes
            .iter()
            .filter(|(id, _)| slot_robot.get(id) == Some(&r))
            .max_by_key(|(_, v)| v[r])
            .map(|(id, _)| *id);
    }
    let mut target_sets = Vec::with_capacity(hist.len());
    for (reports, truth, pose) in &hist {
        for r in 0..n_t {
            if let (Some(id), Some(t)) = (target_slot[r], truth[r])
                && let Some(xy) = reports
                    .iter()
                    .find(|rep| rep.id == id && rep.status == TrackStatus::Confirmed)
                    .and_then(TrackReport::xy)
            {
                target_err[r].push((xy[0] - t[0]).hypot(xy[1] - t[1]));
            }
        }
        let est: Vec<[f64; 2]> = reports
            .iter()
            .filter(|r| r.status == TrackStatus::Confirmed)
            .filter_map(TrackReport::xy)
            .collect();
        let visible: Vec<[f64; 2]> = truth
            .iter()
            .flatten()
            .filter(|t| {
                let dx = t[0] - pose.x;
                let dy = t[1] - pose.y;
                cfg.sensor_range.is_none_or(|rr| dx.hypot(dy) <= rr)
                    && wrap_angle(dy.atan2(dx) - pose.theta).abs() <= 0.5 * cfg.sensor_fov
            })
            .copied()
            .collect();
        target_sets.push((visible, est));
    }
    let (ospa, gospa) = score_targets(&target_sets, 1.0)?;
    let map = tr.map_estimate();
    let mut map_errs = Vec::new();
    for (id, m) in &map {
        if let Some((_, t)) = run.landmarks.iter().find(|(i, _)| i == id) {
            map_errs.push((m[0] - t[0]).hypot(m[1] - t[1]));
        }
    }
    let trajectory = score_trajectory(&robot_est, &robot_true)?;
    let map_score = score_map(&map, &run.landmarks, trajectory.alignment);
    Ok(MrclamResult {
        robot_err,
        epoch_t,
        map_err: mean_var(&map_errs).0,
        landmarks_mapped: map.len(),
        target_err,
        target_slot,
        ospa,
        assoc_accuracy: if tot > 0 {
            ok as f64 / tot as f64
        } else {
            f64::NAN
        },
        assoc_per_target: per,
        assoc_unassigned: unassigned,
        slots_created: last_slots,
        ms_per_step: 1e3 * el / run.frames.len().max(1) as f64,
        robot_est,
        robot_true,
        map,
        trajectory,
        map_score,
        gospa,
        tracks,
        neff,
        resampled,
        landmark_nis,
        epoch_pose,
    })
}
