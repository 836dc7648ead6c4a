//! The simulated runs of spec §4 and their scoring (§4.2): the RBPF ([`run_simulated`],
//! [`run_frames`]) and the EKF-SLAMOT baseline ([`run_simulated_ekf`]) over the frames of
//! `quarry_sim::slamot`, scored by one function ([`score_frames`]).

use quarry_core::{
    Gaussian, LandmarkId, LandmarkStore, MultiTargetTracker, Pose2, Stamp, TrackId, TrackReport,
    TrackStatus,
};
use quarry_sim::slamot::{SlamotFrame, SlamotScenarioConfig, simulate};
use quarry_trackers::ekf_slamot::EkfSlamot;
use quarry_trackers::slamot::{
    DefaultStore, FlatStore, MapStoreKind, SlamotConfig, SlamotObservation, SlamotTracker,
};
use serde::{Deserialize, Serialize};

use super::observation;
use crate::Result;

/// Mean and population variance of a series (spec §4.2); `(NaN, NaN)` for an empty series.
pub fn mean_var(e: &[f64]) -> (f64, f64) {
    if e.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let n = e.len() as f64;
    let m = e.iter().sum::<f64>() / n;
    (m, e.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n)
}

/// Optimal assignment of estimate slots to truth positions by total distance (brute force over
/// permutations; `slots.len()` and `truth.len()` ≤ 8). Returns `pi[slot] = Some(truth index)`.
pub fn assign_slots(slots: &[[f64; 2]], truth: &[[f64; 2]]) -> Vec<Option<usize>> {
    let n = slots.len();
    let m = truth.len();
    let mut best = (f64::INFINITY, vec![None; n]);
    fn rec(
        l: usize,
        slots: &[[f64; 2]],
        truth: &[[f64; 2]],
        used: &mut Vec<bool>,
        cur: &mut Vec<Option<usize>>,
        cost: f64,
        best: &mut (f64, Vec<Option<usize>>),
    ) {
        if cost >= best.0 {
            return;
        }
        if l == slots.len() {
            *best = (cost, cur.clone());
            return;
        }
        let assigned = cur.iter().filter(|c| c.is_some()).count();
        let free_truth = truth.len() - assigned;
        let free_slots = slots.len() - l;
        for t in 0..truth.len() {
            if !used[t] {
                used[t] = true;
                cur[l] = Some(t);
                let d = (slots[l][0] - truth[t][0]).hypot(slots[l][1] - truth[t][1]);
                rec(l + 1, slots, truth, used, cur, cost + d, best);
                used[t] = false;
                cur[l] = None;
            }
        }
        // leave slot unassigned only if there are more slots than truths left
        if free_slots > free_truth {
            rec(l + 1, slots, truth, used, cur, cost, best);
        }
    }
    if n <= 8 && m <= 8 {
        rec(
            0,
            slots,
            truth,
            &mut vec![false; m],
            &mut vec![None; n],
            0.0,
            &mut best,
        );
    }
    best.1
}

/// The result of one simulated run (spec §4.2–4.3).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SimRunResult {
    /// Robot position error per observation epoch.
    pub robot_err: Vec<f64>,
    /// Per true target: position error per epoch from the first target epoch (fixed assignment).
    pub target_err: Vec<Vec<f64>>,
    /// Times \[s\] of the epochs of `robot_err`.
    pub epoch_t: Vec<f64>,
    /// Whether, after t = 40 s, some target's error exceeded 3 m (swap or loss, E4).
    pub swap_or_loss: bool,
    /// Estimated robot trajectory per epoch (x, y, θ).
    pub robot_est: Vec<[f64; 3]>,
    /// True robot trajectory per epoch.
    pub robot_true: Vec<[f64; 3]>,
    /// Estimated target positions per epoch, per true target (NaN before initialisation).
    pub target_est: Vec<Vec<[f64; 2]>>,
    /// True target positions per epoch.
    pub target_true: Vec<Vec<[f64; 2]>>,
    /// Final landmark map estimate (external id, position).
    pub map: Vec<(LandmarkId, [f64; 2])>,
    /// Fraction of epochs with resampling.
    pub resample_rate: f64,
    /// Wall-clock milliseconds per control step.
    pub ms_per_step: f64,
}

/// Runs the tracker (store `S`) over simulated frames and scores it (spec §4.2).
pub fn run_frames<S>(
    cfg: &SlamotConfig,
    frames: &[SlamotFrame],
    initial: Pose2,
    dt_control: f64,
    filter_seed: u64,
) -> Result<SimRunResult>
where
    S: LandmarkStore<Gaussian<2>> + FromIterator<Gaussian<2>> + Send + Sync,
{
    let mut tr = SlamotTracker::<S>::with_store(cfg.clone(), initial, filter_seed)?;
    let mut res = score_frames(frames, dt_control, |stamp, obs| {
        let reports = tr.step(stamp, obs)?;
        Ok((tr.pose_estimate(), reports))
    })?;
    res.map = tr.map_estimate();
    let (e, r) = tr.resample_counts();
    res.resample_rate = if e > 0 { r as f64 / e as f64 } else { 0.0 };
    Ok(res)
}

/// Drives a filter over simulated frames and scores it (spec §4.2): `step` runs one control
/// step and returns the pose estimate and the track reports. `map` and `resample_rate` are left
/// empty / 0 for the caller.
pub fn score_frames(
    frames: &[SlamotFrame],
    dt_control: f64,
    mut step: impl FnMut(Stamp, &SlamotObservation) -> Result<(Pose2, Vec<TrackReport>)>,
) -> Result<SimRunResult> {
    let n_true = frames.first().map_or(0, |f| f.truth.targets.len());
    let mut res = SimRunResult {
        robot_err: Vec::new(),
        target_err: vec![Vec::new(); n_true],
        epoch_t: Vec::new(),
        swap_or_loss: false,
        robot_est: Vec::new(),
        robot_true: Vec::new(),
        target_est: vec![Vec::new(); n_true],
        target_true: vec![Vec::new(); n_true],
        map: Vec::new(),
        resample_rate: 0.0,
        ms_per_step: 0.0,
    };
    // pi: truth index -> slot id (fixed at the first target epoch)
    let mut pi: Option<Vec<Option<TrackId>>> = None;
    let start = std::time::Instant::now();
    for f in frames {
        let (p, reports) = step(Stamp::from_frame(f.k, dt_control), &observation(f))?;
        if !f.observe {
            continue;
        }
        let tp = f.truth.robot;
        res.robot_err.push((p.x - tp.x).hypot(p.y - tp.y));
        res.epoch_t.push(f.t);
        res.robot_est.push([p.x, p.y, p.theta]);
        res.robot_true.push([tp.x, tp.y, tp.theta]);
        let truth_xy: Vec<[f64; 2]> = f.truth.targets.iter().map(|t| [t[0], t[1]]).collect();
        let confirmed: Vec<&TrackReport> = reports
            .iter()
            .filter(|r| r.status == TrackStatus::Confirmed)
            .collect();
        if pi.is_none() && !confirmed.is_empty() {
            let xy: Vec<[f64; 2]> = confirmed.iter().filter_map(|r| r.xy()).collect();
            let a = assign_slots(&xy, &truth_xy);
            let mut map = vec![None; n_true];
            for (s, t) in a.iter().enumerate() {
                if let Some(t) = t {
                    map[*t] = Some(confirmed[s].id);
                }
            }
            pi = Some(map);
        }
        for (l, txy) in truth_xy.iter().enumerate() {
            res.target_true[l].push(*txy);
            let est = pi
                .as_ref()
                .and_then(|m| m[l])
                .and_then(|id| reports.iter().find(|r| r.id == id))
                .and_then(TrackReport::xy);
            match (pi.is_some(), est) {
                (true, Some(e)) => {
                    let d = (e[0] - txy[0]).hypot(e[1] - txy[1]);
                    res.target_err[l].push(d);
                    res.target_est[l].push(e);
                    if f.t > 40.0 && d > 3.0 {
                        res.swap_or_loss = true;
                    }
                }
                (true, None) => {
                    // slot lost (deleted or never assigned): counts as a loss
                    if f.t > 40.0 {
                        res.swap_or_loss = true;
                    }
                    res.target_est[l].push([f64::NAN, f64::NAN]);
                }
                _ => res.target_est[l].push([f64::NAN, f64::NAN]),
            }
        }
    }
    let el = start.elapsed().as_secs_f64();
    res.ms_per_step = 1e3 * el / frames.len().max(1) as f64;
    Ok(res)
}

/// Simulates scenario `scen` with truth seed `truth_seed` and runs the default-store tracker
/// with filter seed `filter_seed`.
pub fn run_simulated(
    cfg: &SlamotConfig,
    scen: &SlamotScenarioConfig,
    truth_seed: u64,
    filter_seed: u64,
) -> Result<SimRunResult> {
    let frames = simulate(scen, truth_seed)?;
    let [x, y, th] = scen.robot_init;
    match cfg.map_store {
        MapStoreKind::Persistent => run_frames::<DefaultStore>(
            cfg,
            &frames,
            Pose2::new(x, y, th),
            scen.dt_control,
            filter_seed,
        ),
        MapStoreKind::Vec => run_frames::<FlatStore>(
            cfg,
            &frames,
            Pose2::new(x, y, th),
            scen.dt_control,
            filter_seed,
        ),
    }
}

/// Simulates scenario `scen` with truth seed `truth_seed` and runs the EKF-SLAMOT baseline on
/// it, scored exactly as [`run_simulated`] scores the RBPF
/// (`resample_rate` is 0).
pub fn run_simulated_ekf(
    cfg: &SlamotConfig,
    scen: &SlamotScenarioConfig,
    truth_seed: u64,
) -> Result<SimRunResult> {
    let frames = simulate(scen, truth_seed)?;
    let [x, y, th] = scen.robot_init;
    let mut ekf = EkfSlamot::new(cfg.clone(), Pose2::new(x, y, th))?;
    let mut res = score_frames(&frames, scen.dt_control, |stamp, obs| {
        let reps = ekf.step(stamp, obs)?;
        Ok((ekf.pose_estimate(), reps))
    })?;
    res.map = ekf.map_estimate();
    Ok(res)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assignment_is_optimal() {
        let a = assign_slots(
            &[[0.0, 0.0], [10.0, 0.0]],
            &[[9.0, 0.0], [1.0, 0.0], [50.0, 0.0]],
        );
        assert_eq!(a, vec![Some(1), Some(0)]);
        let b = assign_slots(&[[0.0, 0.0], [10.0, 0.0], [3.0, 0.0]], &[[9.0, 0.0]]);
        assert_eq!(b, vec![None, Some(0), None]);
    }
}
