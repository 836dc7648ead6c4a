//! Scenario generator of spec 000 (RBPF SLAM + multi-target tracking, "PFJPDA_SLAMOT").
//!
//! A bicycle robot steers towards the centroid of three constant-velocity targets in a
//! 100 m x 100 m world with 49 static landmarks on a jittered grid (spec §3.2). Every control step
//! (Δt_u = 0.025 s) yields a [`SlamotFrame`] with the noisy odometry; every `obs_every`-th step is an
//! observation epoch with range-bearing detections of the landmarks (with their ids) and of the
//! targets (shuffled, no ids; clutter optional). Ground truth rides along in [`SlamotTruth`].
//!
//! Randomness: the seed `s` drives two separate streams, `stream(s, [0])` for the odometry noise
//! and `stream(s, [1])` for the sensor (noise, detections, clutter, shuffling). The filter must use
//! its own stream (spec §3.2, "truth and filter RNG streams separated").
//!
//! ```
//! use quarry_sim::slamot::{simulate, SlamotScenarioConfig};
//! let mut cfg = SlamotScenarioConfig::s0();
//! cfg.duration = 2.0;
//! let frames = simulate(&cfg, 7)?;
//! assert_eq!(frames.len(), 80);
//! assert!(frames[7].observe && frames[7].target_obs.len() == 3);
//! # Ok::<(), quarry_sim::SimError>(())
//! ```

use std::f64::consts::PI;

use quarry_core::rng::stream;
use quarry_core::{CoreError, LandmarkId, Pose2, wrap_angle};
use rand::Rng;
use rand::seq::SliceRandom;
use rand_distr::{Distribution, Normal, Poisson, StandardNormal};
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use crate::SimError;

/// Configuration of the simulated SLAMOT scenario. `Default` is S0 (spec §3.2).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(default))]
pub struct SlamotScenarioConfig {
    /// Control period Δt_u \[s\] (Bailey's FastSLAM simulator default 0.025 s).
    pub dt_control: f64,
    /// Observation epoch every `obs_every` control steps (8, i.e. Δt_z = 0.2 s).
    pub obs_every: u32,
    /// Duration \[s\] (80 s: targets cross x = 9 → 89 inside the world).
    pub duration: f64,
    /// Bicycle wheelbase B \[m\] (4 m).
    pub wheelbase: f64,
    /// Maximum steering angle MAXG \[rad\] (30°).
    pub max_steer: f64,
    /// Maximum steering rate RATEG [rad/s] (20°/s).
    pub steer_rate: f64,
    /// Speed gain k_v [1/s] of V = clamp(k_v d, 0, V_max) (0.2).
    pub speed_gain: f64,
    /// Maximum speed V_max [m/s] (3).
    pub max_speed: f64,
    /// Initial robot pose (x, y, φ) ((4, 54, 0)).
    pub robot_init: [f64; 3],
    /// Targets (x₀, y₀, v_x, v_y) (T1 (9,36,1,0), T2 (9,72,1,−0.3), T3 (9,54,1,0.3)).
    pub targets: Vec<[f64; 4]>,
    /// Truth process noise of the targets σ_a,true [m/s²] (0: exactly constant velocity).
    pub target_truth_sigma_a: f64,
    /// Odometry noise std of the speed σ_V [m/s] (the paper's 0.3).
    pub sigma_v: f64,
    /// Odometry noise std of the steering angle σ_G \[rad\] (the paper's 0.0872).
    pub sigma_g: f64,
    /// Range noise std σ_r \[m\] (0.1).
    pub sigma_r: f64,
    /// Bearing noise std σ_b \[rad\] (1°).
    pub sigma_b: f64,
    /// Sensor range \[m\] (30).
    pub max_range: f64,
    /// Sensor field of view \[rad\], centred on the heading (2π: all around).
    pub fov: f64,
    /// Detection probability of a target (1 in S0, 0.9 in S1). Landmarks are always detected.
    pub p_detect: f64,
    /// Expected clutter detections per scan (Poisson), uniform in range [0, max_range] ×
    /// bearing over the field of view (0 in S0, 2 in S1).
    pub clutter_rate: f64,
    /// Static landmarks (x, y) (the jittered 7×7 grid of [`landmark_layout`]).
    pub landmarks: Vec<[f64; 2]>,
}

impl Default for SlamotScenarioConfig {
    fn default() -> Self {
        Self::s0()
    }
}

/// The 49 landmarks of spec §3.2: (2.5 + 15a + ((3a + 2b) mod 5) − 2, 2.5 + 15b + ((2a + 3b + 1)
/// mod 5) − 2), a, b = 0..6. Deterministic (no RNG).
pub fn landmark_layout() -> Vec<[f64; 2]> {
    let mut out = Vec::with_capacity(49);
    for a in 0..7_u32 {
        for b in 0..7_u32 {
            let x = 2.5 + 15.0 * f64::from(a) + f64::from((3 * a + 2 * b) % 5) - 2.0;
            let y = 2.5 + 15.0 * f64::from(b) + f64::from((2 * a + 3 * b + 1) % 5) - 2.0;
            out.push([x, y]);
        }
    }
    out
}

impl SlamotScenarioConfig {
    /// S0: the paper's scenario as the spec designs it (§3.2).
    pub fn s0() -> Self {
        Self {
            dt_control: 0.025,
            obs_every: 8,
            duration: 80.0,
            wheelbase: 4.0,
            max_steer: 30f64.to_radians(),
            steer_rate: 20f64.to_radians(),
            speed_gain: 0.2,
            max_speed: 3.0,
            robot_init: [4.0, 54.0, 0.0],
            targets: vec![
                [9.0, 36.0, 1.0, 0.0],
                [9.0, 72.0, 1.0, -0.3],
                [9.0, 54.0, 1.0, 0.3],
            ],
            target_truth_sigma_a: 0.0,
            sigma_v: 0.3,
            sigma_g: 0.0872,
            sigma_r: 0.1,
            sigma_b: 1f64.to_radians(),
            max_range: 30.0,
            fov: 2.0 * PI,
            p_detect: 1.0,
            clutter_rate: 0.0,
            landmarks: landmark_layout(),
        }
    }

    /// S1: S0 with target detection probability 0.9 and Poisson(2) clutter per scan (§4.3 E6).
    pub fn s1() -> Self {
        Self {
            p_detect: 0.9,
            clutter_rate: 2.0,
            ..Self::s0()
        }
    }

    /// Observation period Δt_z \[s\].
    pub fn dt_observe(&self) -> f64 {
        self.dt_control * f64::from(self.obs_every)
    }

    /// Number of control steps of a run.
    pub fn steps(&self) -> usize {
        (self.duration / self.dt_control).round() as usize
    }

    /// Checks every field: finite, positive where it must be, probabilities in [0, 1].
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |what: &'static str, reason: &str| {
            Err(SimError::Core(CoreError::InvalidParameter {
                name: what,
                reason: reason.to_string(),
            }))
        };
        let pos = [
            ("dt_control", self.dt_control),
            ("duration", self.duration),
            ("wheelbase", self.wheelbase),
            ("max_range", self.max_range),
            ("fov", self.fov),
        ];
        for (n, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return bad(n, "must be finite and > 0");
            }
        }
        let nonneg = [
            ("max_steer", self.max_steer),
            ("steer_rate", self.steer_rate),
            ("speed_gain", self.speed_gain),
            ("max_speed", self.max_speed),
            ("target_truth_sigma_a", self.target_truth_sigma_a),
            ("sigma_v", self.sigma_v),
            ("sigma_g", self.sigma_g),
            ("sigma_r", self.sigma_r),
            ("sigma_b", self.sigma_b),
            ("clutter_rate", self.clutter_rate),
        ];
        for (n, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return bad(n, "must be finite and >= 0");
            }
        }
        if self.obs_every == 0 {
            return bad("obs_every", "must be >= 1");
        }
        if !(0.0..=1.0).contains(&self.p_detect) {
            return bad("p_detect", "must be in [0, 1]");
        }
        if self.targets.is_empty() {
            return bad(
                "targets",
                "at least one target is needed (the robot steers to them)",
            );
        }
        if self.robot_init.iter().any(|v| !v.is_finite())
            || self.targets.iter().flatten().any(|v| !v.is_finite())
            || self.landmarks.iter().flatten().any(|v| !v.is_finite())
        {
            return Err(SimError::Core(CoreError::NonFinite {
                what: "scenario initial state (robot, targets or landmarks)",
            }));
        }
        Ok(())
    }
}

/// Ground truth of one control step.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct SlamotTruth {
    /// True robot pose.
    pub robot: Pose2,
    /// True commanded control (V, G).
    pub control: (f64, f64),
    /// True target states (x, y, v_x, v_y).
    pub targets: Vec<[f64; 4]>,
    /// For each entry of `target_obs`: the index of the target that produced it, `None` = clutter.
    pub target_obs_source: Vec<Option<usize>>,
}

/// One control step of the scenario: what the robot's sensors report, plus the truth.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct SlamotFrame {
    /// Control step index k (1-based: frame k is the state after k control steps).
    pub k: u64,
    /// Time \[s\] = k Δt_u.
    pub t: f64,
    /// Duration of this control step \[s\].
    pub dt: f64,
    /// Odometry (V, G): the commanded control plus noise N(0, diag(σ_V², σ_G²)).
    pub odometry: (f64, f64),
    /// True when this step is an observation epoch (detections may still be empty).
    pub observe: bool,
    /// Landmark detections: (landmark id, [range, bearing]).
    pub landmark_obs: Vec<(LandmarkId, [f64; 2])>,
    /// Target detections [range, bearing], randomly permuted, no identity.
    pub target_obs: Vec<[f64; 2]>,
    /// Ground truth.
    pub truth: SlamotTruth,
}

fn range_bearing(pose: &Pose2, p: [f64; 2]) -> [f64; 2] {
    let dx = p[0] - pose.x;
    let dy = p[1] - pose.y;
    [dx.hypot(dy), wrap_angle(dy.atan2(dx) - pose.theta)]
}

fn normal(sd: f64) -> Result<Normal<f64>, SimError> {
    Normal::new(0.0, sd).map_err(|_| {
        SimError::Core(CoreError::InvalidParameter {
            name: "noise std",
            reason: format!("{sd} is not a valid standard deviation"),
        })
    })
}

/// The steering law of spec §2.3 (Bailey's waypoint steering with the centroid as waypoint).
/// Returns the new (V, G) from the current pose, current steering angle and waypoint.
pub fn steer(cfg: &SlamotScenarioConfig, pose: &Pose2, g: f64, waypoint: [f64; 2]) -> (f64, f64) {
    let dx = waypoint[0] - pose.x;
    let dy = waypoint[1] - pose.y;
    let d = dx.hypot(dy);
    let v = (cfg.speed_gain * d).clamp(0.0, cfg.max_speed);
    let max_delta = cfg.steer_rate * cfg.dt_control;
    let dg = wrap_angle(dy.atan2(dx) - pose.theta - g).clamp(-max_delta, max_delta);
    let g = (g + dg).clamp(-cfg.max_steer, cfg.max_steer);
    (v, g)
}

/// The bicycle model of spec §2.3 (used by the truth; the filter uses quarry-filter's).
pub fn bicycle_step(pose: &Pose2, v: f64, g: f64, wheelbase: f64, dt: f64) -> Pose2 {
    Pose2::new(
        pose.x + v * dt * (pose.theta + g).cos(),
        pose.y + v * dt * (pose.theta + g).sin(),
        wrap_angle(pose.theta + v * dt * g.sin() / wheelbase),
    )
}

/// Simulates one run. Frame `k - 1` of the result holds control step k = 1..steps.
pub fn simulate(cfg: &SlamotScenarioConfig, seed: u64) -> Result<Vec<SlamotFrame>, SimError> {
    cfg.validate()?;
    let mut odo_rng = stream(seed, &[0]);
    let mut sen_rng = stream(seed, &[1]);
    let nv = normal(cfg.sigma_v)?;
    let ng = normal(cfg.sigma_g)?;
    let nr = normal(cfg.sigma_r)?;
    let nb = normal(cfg.sigma_b)?;
    let clutter = if cfg.clutter_rate > 0.0 {
        Some(Poisson::new(cfg.clutter_rate).map_err(|_| {
            SimError::Core(CoreError::InvalidParameter {
                name: "clutter_rate",
                reason: "invalid Poisson rate".into(),
            })
        })?)
    } else {
        None
    };
    let steps = cfg.steps();
    let dt = cfg.dt_control;
    let mut pose = Pose2::new(cfg.robot_init[0], cfg.robot_init[1], cfg.robot_init[2]);
    let mut g = 0.0;
    let mut targets = cfg.targets.clone();
    let mut frames = Vec::with_capacity(steps);
    for k in 1..=steps as u64 {
        // 1. true control from the true centroid, then propagate robot and targets.
        let n = targets.len() as f64;
        let c = [
            targets.iter().map(|t| t[0]).sum::<f64>() / n,
            targets.iter().map(|t| t[1]).sum::<f64>() / n,
        ];
        let (v, g_new) = steer(cfg, &pose, g, c);
        g = g_new;
        pose = bicycle_step(&pose, v, g, cfg.wheelbase, dt);
        for t in &mut targets {
            if cfg.target_truth_sigma_a > 0.0 {
                let ax: f64 = odo_rng.sample::<f64, _>(StandardNormal) * cfg.target_truth_sigma_a;
                let ay: f64 = odo_rng.sample::<f64, _>(StandardNormal) * cfg.target_truth_sigma_a;
                t[0] += t[2] * dt + 0.5 * ax * dt * dt;
                t[1] += t[3] * dt + 0.5 * ay * dt * dt;
                t[2] += ax * dt;
                t[3] += ay * dt;
            } else {
                t[0] += t[2] * dt;
                t[1] += t[3] * dt;
            }
        }
        let odometry = (v + nv.sample(&mut odo_rng), g + ng.sample(&mut odo_rng));
        let observe = k % u64::from(cfg.obs_every) == 0;
        let mut landmark_obs = Vec::new();
        let mut tagged: Vec<([f64; 2], Option<usize>)> = Vec::new();
        if observe {
            let visible = |z: [f64; 2]| z[0] <= cfg.max_range && z[1].abs() <= cfg.fov / 2.0;
            for (i, lm) in cfg.landmarks.iter().enumerate() {
                let z = range_bearing(&pose, *lm);
                if visible(z) {
                    landmark_obs.push((
                        LandmarkId(i as u32),
                        [
                            z[0] + nr.sample(&mut sen_rng),
                            wrap_angle(z[1] + nb.sample(&mut sen_rng)),
                        ],
                    ));
                }
            }
            for (l, t) in targets.iter().enumerate() {
                let z = range_bearing(&pose, [t[0], t[1]]);
                let detected = cfg.p_detect >= 1.0 || sen_rng.random::<f64>() < cfg.p_detect;
                if visible(z) && detected {
                    tagged.push((
                        [
                            z[0] + nr.sample(&mut sen_rng),
                            wrap_angle(z[1] + nb.sample(&mut sen_rng)),
                        ],
                        Some(l),
                    ));
                }
            }
            if let Some(pois) = &clutter {
                let m = pois.sample(&mut sen_rng) as usize;
                for _ in 0..m {
                    let r = sen_rng.random::<f64>() * cfg.max_range;
                    let b = wrap_angle((sen_rng.random::<f64>() - 0.5) * cfg.fov.min(2.0 * PI));
                    tagged.push(([r, b], None));
                }
            }
            tagged.shuffle(&mut sen_rng);
        }
        frames.push(SlamotFrame {
            k,
            t: k as f64 * dt,
            dt,
            odometry,
            observe,
            landmark_obs,
            target_obs: tagged.iter().map(|(z, _)| *z).collect(),
            truth: SlamotTruth {
                robot: pose,
                control: (v, g),
                targets: targets.clone(),
                target_obs_source: tagged.iter().map(|(_, s)| *s).collect(),
            },
        });
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_matches_formula_and_clears_path() {
        let l = landmark_layout();
        assert_eq!(l.len(), 49);
        assert_eq!(l[0], [0.5, 1.5]); // a = b = 0: (2.5 + 0 - 2, 2.5 + 1 - 2)
        // a = 1, b = 2: x = 2.5 + 15 + (7 mod 5) - 2 = 17.5; y = 2.5 + 30 + (9 mod 5) - 2 = 34.5
        assert_eq!(l[9], [17.5, 34.5]);
        for p in &l {
            assert!((0.0..=100.0).contains(&p[0]) && (0.0..=100.0).contains(&p[1]));
        }
    }

    #[test]
    fn deterministic_by_seed_and_seed_matters() {
        let mut cfg = SlamotScenarioConfig::s1();
        cfg.duration = 5.0;
        let a = simulate(&cfg, 3).unwrap();
        let b = simulate(&cfg, 3).unwrap();
        let c = simulate(&cfg, 4).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
        // truth does not depend on the sensor stream: same trajectory for every seed
        assert_eq!(a[150].truth.robot, c[150].truth.robot);
    }

    #[test]
    fn targets_two_and_three_cross_at_39_63() {
        let cfg = SlamotScenarioConfig::s0();
        let f = simulate(&cfg, 0).unwrap();
        let at30 = &f[(30.0 / cfg.dt_control).round() as usize - 1];
        assert!((at30.t - 30.0).abs() < 1e-9);
        for l in [1, 2] {
            let t = at30.truth.targets[l];
            assert!(
                (t[0] - 39.0).abs() < 1e-6 && (t[1] - 63.0).abs() < 1e-6,
                "{t:?}"
            );
        }
        // the robot follows the centroid (on y = 54) and trails it by a few metres
        let end = f.last().unwrap();
        let c = 9.0 + 80.0;
        assert!(
            (end.truth.robot.y - 54.0).abs() < 2.0,
            "{:?}",
            end.truth.robot
        );
        assert!(end.truth.robot.x < c && end.truth.robot.x > c - 10.0);
    }

    #[test]
    fn measurement_statistics() {
        let cfg = SlamotScenarioConfig::s0();
        let f = simulate(&cfg, 11).unwrap();
        let mut res_r = Vec::new();
        let mut res_b = Vec::new();
        let mut n_lm = Vec::new();
        for fr in f.iter().filter(|f| f.observe) {
            assert_eq!(fr.target_obs.len(), 3);
            n_lm.push(fr.landmark_obs.len());
            for (z, s) in fr.target_obs.iter().zip(&fr.truth.target_obs_source) {
                let t = fr.truth.targets[s.unwrap()];
                let zt = range_bearing(&fr.truth.robot, [t[0], t[1]]);
                res_r.push(z[0] - zt[0]);
                res_b.push(wrap_angle(z[1] - zt[1]));
            }
        }
        assert_eq!(n_lm.len(), 400);
        let sd = |v: &[f64]| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            (
                m,
                (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt(),
            )
        };
        let (mr, sr) = sd(&res_r);
        let (mb, sb) = sd(&res_b);
        assert!(mr.abs() < 0.01 && (sr - 0.1).abs() < 0.006, "{mr} {sr}");
        assert!(
            mb.abs() < 0.0015 && (sb - cfg.sigma_b).abs() < 0.0015,
            "{mb} {sb}"
        );
        n_lm.sort_unstable();
        let med = n_lm[n_lm.len() / 2];
        assert!((8..=16).contains(&med), "median landmarks in view {med}");
    }

    #[test]
    fn s1_has_misses_and_clutter() {
        let cfg = SlamotScenarioConfig::s1();
        let f = simulate(&cfg, 5).unwrap();
        let epochs: Vec<_> = f.iter().filter(|f| f.observe).collect();
        let real: usize = epochs
            .iter()
            .map(|f| {
                f.truth
                    .target_obs_source
                    .iter()
                    .filter(|s| s.is_some())
                    .count()
            })
            .sum();
        let clutter: usize = epochs
            .iter()
            .map(|f| {
                f.truth
                    .target_obs_source
                    .iter()
                    .filter(|s| s.is_none())
                    .count()
            })
            .sum();
        let pd = real as f64 / (3.0 * epochs.len() as f64);
        let rate = clutter as f64 / epochs.len() as f64;
        assert!((pd - 0.9).abs() < 0.03, "{pd}");
        assert!((rate - 2.0).abs() < 0.25, "{rate}");
    }

    #[test]
    fn invalid_config_is_an_error() {
        let mut cfg = SlamotScenarioConfig::s0();
        cfg.sigma_r = f64::NAN;
        assert!(simulate(&cfg, 0).is_err());
        let mut cfg = SlamotScenarioConfig::s0();
        cfg.targets.clear();
        assert!(simulate(&cfg, 0).is_err());
        let mut cfg = SlamotScenarioConfig::s0();
        cfg.p_detect = 1.5;
        assert!(simulate(&cfg, 0).is_err());
    }
}
