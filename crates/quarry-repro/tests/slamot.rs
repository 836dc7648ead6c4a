//! Paper 000 (SLAMOT, EKF-SLAMOT) on the simulated scenarios S0/S1 and on MRCLAM: the scenario
//! tests of the tracker and its baseline (one test binary for the whole paper).
//!
//! The reproduction protocol (ignored by default; the numbers of docs/slamot.md):
//! `cargo test -p quarry-repro --release --test slamot protocol -- --ignored --nocapture`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
#![allow(clippy::needless_range_loop)] // l indexes several parallel per-target arrays

use nalgebra::DMatrix;
use quarry_core::{MultiTargetTracker, Pose2, Stamp};
use quarry_repro::slamot::{
    filter_seed, mean_var, mrclam_config, observation, run_mrclam, run_simulated,
    run_simulated_ekf, smooth_mrclam,
};
use quarry_sim::slamot::SlamotScenarioConfig;
use quarry_trackers::ekf_slamot::EkfSlamot;
use quarry_trackers::slamot::{
    AssociationMode, MapStoreKind, SlamotConfig, SlamotTracker, TargetInit, TargetWeight,
};

#[test]
fn s0_three_runs_beat_the_paper() {
    let scen = SlamotScenarioConfig::s0();
    let cfg = SlamotConfig::default();
    let paper = [0.923, 1.544, 1.952];
    for r in 0..3 {
        let res = run_simulated(&cfg, &scen, r, filter_seed(r, 50)).unwrap();
        let (er, _) = mean_var(&res.robot_err);
        assert_eq!(res.robot_err.len(), 400);
        assert!(er < 0.452, "run {r}: robot {er}");
        for l in 0..3 {
            let (el, _) = mean_var(&res.target_err[l]);
            assert!(el < paper[l], "run {r} target {l}: {el}");
            assert!(el > 0.02, "suspiciously small {el}");
        }
        assert!(!res.swap_or_loss, "run {r} swapped");
        assert!(res.resample_rate > 0.2 && res.resample_rate <= 1.0);
    }
}

#[test]
fn deterministic_by_seed() {
    let mut scen = SlamotScenarioConfig::s0();
    scen.duration = 10.0;
    let cfg = SlamotConfig {
        particles: 20,
        ..SlamotConfig::default()
    };
    let a = run_simulated(&cfg, &scen, 1, 9).unwrap();
    let b = run_simulated(&cfg, &scen, 1, 9).unwrap();
    let c = run_simulated(&cfg, &scen, 1, 10).unwrap();
    assert_eq!(a.robot_est, b.robot_est);
    assert_eq!(a.target_err, b.target_err);
    assert_ne!(a.robot_est, c.robot_est);
}

#[test]
fn mrclam_robot1_if_present() {
    let dir = std::env::var("QUARRY_SHARED").map_or_else(
        |_| std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
        std::path::PathBuf::from,
    );
    let dir = dir.join("data/mrclam-6");
    if !dir.join("Barcodes.dat").exists() {
        eprintln!("skipping: {} not found", dir.display());
        return;
    }
    let run = quarry_data::mrclam::load(&dir, 1).unwrap();
    let res = run_mrclam(&mrclam_config(20), &run, 1).unwrap();
    let (er, _) = mean_var(&res.robot_err);
    let te: Vec<f64> = res.target_err.iter().map(|e| mean_var(e).0).collect();
    eprintln!(
        "robot {er:.3} map {:.3} ({} lm) targets {te:?} slots {:?} ospa {:.3} acc {:.3} per {:?} created {} ms/step {:.3}",
        res.map_err,
        res.landmarks_mapped,
        res.target_slot,
        res.ospa,
        res.assoc_accuracy,
        res.assoc_per_target,
        res.slots_created,
        res.ms_per_step
    );
    let n = res.robot_err.len();
    let series: Vec<String> = (0..20)
        .map(|i| {
            format!(
                "{:.0}s:{:.2}",
                res.epoch_t[i * n / 20],
                res.robot_err[i * n / 20]
            )
        })
        .collect();
    eprintln!("{}", series.join(" "));
    // measured (N = 20, seed 1; own-stamp timing, the stop-29 preset: robot 1's estimated
    // noise, no landmark gate): robot 0.59 m, map 0.99 m, association 0.80 (the earlier preset,
    // fitted noise + gate: 0.55 / 0.64 / 0.79; at the next odometry stamp 0.73 / 1.22 / 0.77).
    // With the measured target values of stop 32 (P_D 0.36, mean-reverting robots, tracks
    // deleted past 1 m σ): robot 0.65 m, map 0.76 m, association 0.921 from 31 slots (0.80 from
    // 73 slots before: a track died after 2-4 s in view without a detection and was re-born)
    assert!(er < 1.0, "robot error {er}");
    assert!(res.map_err < 1.6, "map error {}", res.map_err);
    assert!(res.assoc_accuracy > 0.88, "{}", res.assoc_accuracy);
    assert!(res.slots_created <= 45, "{} slots", res.slots_created);
    assert!(
        res.target_slot.iter().all(Option::is_some),
        "every robot tracked"
    );
    // the batch smoother over the same run (docs/slamot.md, "Smoothing"): measured 0.156 m robot
    // error, 0.144 m map error with every filter seed (the optimum does not depend on the
    // start); calibrated, the odometry leads the motion by 0.23 s and over-reads the turn rate
    let sm = smooth_mrclam(&mrclam_config(20), &run, &res, false).unwrap();
    eprintln!(
        "smoothed: robot {:.3} (max {:.3}) map {:.3}, {} iterations",
        sm.trajectory.mean, sm.trajectory.max, sm.map_err, sm.iterations
    );
    assert!(sm.converged);
    assert!(
        sm.trajectory.mean < 0.2,
        "smoothed robot error {}",
        sm.trajectory.mean
    );
    assert!(
        sm.trajectory.max < 0.5,
        "smoothed max {}",
        sm.trajectory.max
    );
    assert!(sm.map_err < 0.2, "smoothed map error {}", sm.map_err);
    let cal = smooth_mrclam(&mrclam_config(20), &run, &res, true).unwrap();
    eprintln!("calibration {:?}", cal.calibration);
    assert!(
        (0.15..0.3).contains(&cal.calibration[3]),
        "{:?}",
        cal.calibration
    );
    assert!(
        (0.85..0.98).contains(&cal.calibration[1]),
        "{:?}",
        cal.calibration
    );
}

/// The reproduction protocol of spec §4.3 (E1, E4, E6, part of E2); prints a table.
/// `cargo test -p quarry-repro --release --test slamot protocol -- --ignored --nocapture`
#[test]
#[ignore = "minutes in debug; the reproduction numbers of docs/slamot.md"]
fn protocol() {
    let runs: u64 = std::env::var("SLAMOT_RUNS").map_or(20, |v| v.parse().unwrap());
    let s1 = |mode| SlamotConfig {
        association: mode,
        ..SlamotConfig::s1()
    };
    let cases: Vec<(&str, SlamotConfig, SlamotScenarioConfig)> = vec![
        (
            "S0 jpda",
            SlamotConfig::default(),
            SlamotScenarioConfig::s0(),
        ),
        (
            "S0 paper",
            SlamotConfig {
                association: AssociationMode::Paper,
                ..SlamotConfig::default()
            },
            SlamotScenarioConfig::s0(),
        ),
        (
            "S0 jpda+eq11",
            SlamotConfig {
                target_weight: TargetWeight::PaperEq11,
                ..SlamotConfig::default()
            },
            SlamotScenarioConfig::s0(),
        ),
        (
            "S0 jipda",
            SlamotConfig {
                association: AssociationMode::Jipda,
                ..SlamotConfig::default()
            },
            SlamotScenarioConfig::s0(),
        ),
        (
            "S1 jpda",
            s1(AssociationMode::Jpda),
            SlamotScenarioConfig::s1(),
        ),
        (
            "S1 jpda first-n-init",
            SlamotConfig {
                target_init: TargetInit::FirstN,
                ..SlamotConfig::s1()
            },
            SlamotScenarioConfig::s1(),
        ),
        (
            "S0 jpda two-point-init",
            SlamotConfig {
                target_init: TargetInit::TwoPoint { max_speed: 3.0 },
                ..SlamotConfig::default()
            },
            SlamotScenarioConfig::s0(),
        ),
        (
            "EKF S0 jpda",
            SlamotConfig::default(),
            SlamotScenarioConfig::s0(),
        ),
        (
            "EKF S0 paper",
            SlamotConfig {
                association: AssociationMode::Paper,
                ..SlamotConfig::default()
            },
            SlamotScenarioConfig::s0(),
        ),
        (
            "EKF S1 jpda",
            s1(AssociationMode::Jpda),
            SlamotScenarioConfig::s1(),
        ),
        (
            "EKF S1 paper",
            s1(AssociationMode::Paper),
            SlamotScenarioConfig::s1(),
        ),
        (
            "EKF S1 jipda",
            s1(AssociationMode::Jipda),
            SlamotScenarioConfig::s1(),
        ),
        (
            "S1 paper",
            s1(AssociationMode::Paper),
            SlamotScenarioConfig::s1(),
        ),
        (
            "S1 jipda",
            s1(AssociationMode::Jipda),
            SlamotScenarioConfig::s1(),
        ),
    ];
    let only = std::env::var("SLAMOT_CASE").unwrap_or_default();
    for (name, cfg, scen) in cases {
        if !name.contains(only.as_str()) {
            continue;
        }
        let mut rm = Vec::new();
        let mut rv = Vec::new();
        let mut tm = vec![Vec::new(); 3];
        let mut tv = vec![Vec::new(); 3];
        let mut losses = 0;
        let mut rs = 0.0;
        let mut ms = 0.0;
        // E5: correlation times [s] of the robot and target error series
        let mut ct = vec![Vec::new(); 4];
        for r in 0..runs {
            let res = if name.starts_with("EKF") {
                run_simulated_ekf(&cfg, &scen, r).unwrap()
            } else {
                run_simulated(&cfg, &scen, r, filter_seed(r, cfg.particles)).unwrap()
            };
            let (m, v) = mean_var(&res.robot_err);
            rm.push(m);
            rv.push(v);
            for l in 0..3 {
                let (m, v) = mean_var(&res.target_err[l]);
                tm[l].push(m);
                tv[l].push(v);
            }
            losses += usize::from(res.swap_or_loss);
            let dt_z = scen.dt_observe();
            for (i, e) in std::iter::once(&res.robot_err)
                .chain(&res.target_err)
                .enumerate()
            {
                if let Ok(Some(t)) = quarry_eval::position::correlation_time(e, dt_z) {
                    ct[i].push(t);
                }
            }
            rs += res.resample_rate;
            ms += res.ms_per_step;
        }
        let f = |v: &[f64]| {
            let mn = v.iter().copied().fold(f64::INFINITY, f64::min);
            let mx = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            format!("{:.3} [{mn:.3}, {mx:.3}]", mean_var(v).0)
        };
        eprintln!(
            "{name}: robot {} var {:.4} | t1 {} var {:.4} | t2 {} var {:.4} | t3 {} var {:.4} | losses {losses}/{runs} | resample {:.2} | ms/step {:.3}",
            f(&rm),
            mean_var(&rv).0,
            f(&tm[0]),
            mean_var(&tv[0]).0,
            f(&tm[1]),
            mean_var(&tv[1]).0,
            f(&tm[2]),
            mean_var(&tv[2]).0,
            rs / runs as f64,
            ms / runs as f64
        );
        eprintln!(
            "{name}: E5 correlation time [s] robot {:.2} targets {:.2} {:.2} {:.2} (runs with a value: {} {} {} {})",
            mean_var(&ct[0]).0,
            mean_var(&ct[1]).0,
            mean_var(&ct[2]).0,
            mean_var(&ct[3]).0,
            ct[0].len(),
            ct[1].len(),
            ct[2].len(),
            ct[3].len()
        );
    }
    if let Ok(ns) = std::env::var("SLAMOT_SWEEP") {
        for n in ns.split(',').map(|v| v.parse::<usize>().unwrap()) {
            let cfg = SlamotConfig {
                particles: n,
                ..SlamotConfig::default()
            };
            let mut rm = Vec::new();
            let mut tm = vec![Vec::new(); 3];
            for r in 0..runs {
                let res =
                    run_simulated(&cfg, &SlamotScenarioConfig::s0(), r, filter_seed(r, n)).unwrap();
                rm.push(mean_var(&res.robot_err).0);
                for l in 0..3 {
                    tm[l].push(mean_var(&res.target_err[l]).0);
                }
            }
            let (m, v) = mean_var(&rm);
            eprintln!(
                "sweep N {n}: robot {m:.4} (se {:.4}) targets {:.4} {:.4} {:.4}",
                (v / (runs as f64 - 1.0).max(1.0)).sqrt(),
                mean_var(&tm[0]).0,
                mean_var(&tm[1]).0,
                mean_var(&tm[2]).0
            );
        }
    }
}

/// Spec test 28: S1 (P_D 0.9, Poisson(2) clutter), `Jpda`, N = 50, 20 runs: at most 2 runs
/// lose a target. With the spec's first-n initiation 10 of these 20 runs lose one (a clutter
/// point among the first 3 detections); two-point initiation (A19) loses none (measured 0/20).
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "20 runs: seconds in release, minutes in debug"
)]
fn s1_stress_at_most_two_losses() {
    let scen = SlamotScenarioConfig::s1();
    let cfg = SlamotConfig::s1();
    let mut losses = 0;
    let mut bad_init = 0;
    for r in 0..20 {
        let res = run_simulated(&cfg, &scen, r, filter_seed(r, 50)).unwrap();
        losses += usize::from(res.swap_or_loss);
        bad_init += usize::from(res.target_err.iter().any(|e| e[0] > 3.0));
        let (er, _) = mean_var(&res.robot_err);
        assert!(er < 0.452, "run {r}: robot {er}");
    }
    assert!(losses <= 2, "{losses}/20 runs lost a target");
    assert_eq!(bad_init, 0, "a slot started on clutter");
}

#[test]
fn paper_and_jipda_modes_run_s1() {
    let mut scen = SlamotScenarioConfig::s1();
    scen.duration = 20.0;
    for mode in [AssociationMode::Paper, AssociationMode::Jipda] {
        let cfg = SlamotConfig {
            particles: 20,
            association: mode,
            p_detect: 0.9,
            clutter_density: 2.0 / (30.0 * 2.0 * std::f64::consts::PI),
            ..SlamotConfig::default()
        };
        let r = run_simulated(&cfg, &scen, 2, 3).unwrap();
        assert!(r.robot_err.iter().all(|e| e.is_finite()));
        let (er, _) = mean_var(&r.robot_err);
        assert!(er < 1.0, "{mode:?}: {er}");
    }
}

/// (From the tracker's `errors_not_panics`; the simulator half.)
#[test]
fn vec_store_is_bit_identical_to_the_tree() {
    // the Vec store gives bit-identical results to the persistent tree
    let mut scen = SlamotScenarioConfig::s0();
    scen.duration = 8.0;
    let mut cfg = SlamotConfig {
        particles: 10,
        ..SlamotConfig::default()
    };
    let a = run_simulated(&cfg, &scen, 4, 5).unwrap();
    cfg.map_store = MapStoreKind::Vec;
    let b = run_simulated(&cfg, &scen, 4, 5).unwrap();
    assert_eq!(a.robot_est, b.robot_est);
    assert_eq!(a.map, b.map);
}

#[test]
fn ekf_covariance_stays_symmetric_and_pd() {
    let mut scen = SlamotScenarioConfig::s0();
    scen.duration = 10.0;
    let frames = quarry_sim::slamot::simulate(&scen, 2).unwrap();
    let mut ekf = EkfSlamot::new(SlamotConfig::default(), Pose2::new(4.0, 54.0, 0.0)).unwrap();
    for f in &frames {
        ekf.step(Stamp::from_frame(f.k, 0.025), &observation(f))
            .unwrap();
    }
    let d = ekf.dim();
    assert_eq!(d, 3 + 2 * ekf.map_estimate().len() + 12);
    let p = DMatrix::from_fn(d, d, |i, j| ekf.covariance()[(i, j)]);
    assert!((&p - p.transpose()).amax() < 1e-12 * p.amax());
    assert!(p.cholesky().is_some(), "P not positive definite");
}

/// With zero control noise and (almost) noise-free sensing the joint EKF is the truth.
#[test]
fn ekf_near_noise_free_is_exact() {
    let mut scen = SlamotScenarioConfig::s0();
    scen.duration = 20.0;
    scen.sigma_v = 0.0;
    scen.sigma_g = 0.0;
    scen.sigma_r = 1e-4;
    scen.sigma_b = 1e-5;
    let cfg = SlamotConfig {
        control_noise: [1e-4, 1e-5],
        meas_noise: [1e-4, 1e-5],
        ..SlamotConfig::default()
    };
    let res = run_simulated_ekf(&cfg, &scen, 3).unwrap();
    let (er, _) = mean_var(&res.robot_err);
    assert!(er < 0.01, "robot {er}");
    for e in &res.target_err {
        let (m, _) = mean_var(e);
        assert!(m < 0.05, "target {m}");
    }
}

#[test]
fn ekf_s0_runs_beat_the_paper() {
    let scen = SlamotScenarioConfig::s0();
    let paper = [0.923, 1.544, 1.952];
    for r in 0..2 {
        let res = run_simulated_ekf(&SlamotConfig::default(), &scen, r).unwrap();
        let (er, _) = mean_var(&res.robot_err);
        assert!(er < 0.452, "run {r}: robot {er}");
        for (l, bound) in paper.iter().enumerate() {
            let (el, _) = mean_var(&res.target_err[l]);
            assert!(el < *bound && el > 0.02, "run {r} target {l}: {el}");
        }
        assert!(!res.swap_or_loss);
    }
}

/// One particle with no control noise: the RBPF's pose is exact and its landmarks and targets
/// are independent EKFs; the joint EKF with zero control noise has P_R· = 0 and must give the
/// same target estimates (same association, same updates).
#[test]
fn ekf_matches_a_one_particle_rbpf_without_pose_noise() {
    let mut scen = SlamotScenarioConfig::s0();
    scen.duration = 15.0;
    scen.sigma_v = 0.0;
    scen.sigma_g = 0.0;
    let frames = quarry_sim::slamot::simulate(&scen, 5).unwrap();
    let cfg = SlamotConfig {
        particles: 1,
        control_noise: [0.0, 0.0],
        ..SlamotConfig::default()
    };
    let init = Pose2::new(4.0, 54.0, 0.0);
    let mut pf = SlamotTracker::new(cfg.clone(), init, 1).unwrap();
    let mut ekf = EkfSlamot::new(cfg, init).unwrap();
    for f in &frames {
        let s = Stamp::from_frame(f.k, 0.025);
        let o = observation(f);
        let a = pf.step(s, &o).unwrap();
        let b = ekf.step(s, &o).unwrap();
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            let (xa, xb) = (x.xy().unwrap(), y.xy().unwrap());
            assert!((xa[0] - xb[0]).abs() < 1e-6 && (xa[1] - xb[1]).abs() < 1e-6);
        }
    }
    let p = ekf.pose_estimate();
    let q = pf.pose_estimate();
    assert!((p.x - q.x).abs() < 1e-9 && (p.theta - q.theta).abs() < 1e-9);
}

/// A synthetic MRCLAM recording: robot 1 drives an arc at 1 m/s with odometry at 5 Hz, and sees
/// four landmarks (noise-free) 20 ms after every odometry stamp. Applied at the end of its
/// odometry interval, each measurement is 180 ms (0.18 m) late and pulls the pose back along the
/// path; applied at its own stamp it agrees with the motion.
fn synthetic_recording() -> Vec<String> {
    use std::fmt::Write as _;
    let h = "# a\n# b\n# c\n# d\n";
    let lms = [[3.0, 4.0], [8.0, -2.0], [12.0, 5.0], [6.0, 9.0]];
    let (v, w) = (1.0, 0.1);
    let pose = |t: f64| -> [f64; 3] {
        let th = w * t;
        [(v / w) * th.sin(), (v / w) * (1.0 - th.cos()), th]
    };
    let mut barcodes = format!("{h}1 5\n2 14\n");
    let mut landmarks = h.to_string();
    for (i, l) in lms.iter().enumerate() {
        let _ = writeln!(barcodes, "{} {}", 6 + i, 60 + i);
        let _ = writeln!(landmarks, "{} {} {} 0 0", 6 + i, l[0], l[1]);
    }
    let t0 = 1000.0;
    let mut odo = h.to_string();
    let mut meas = h.to_string();
    for k in 0..50 {
        let t = 0.2 * f64::from(k);
        let _ = writeln!(odo, "{:.3} {v} {w}", t0 + t);
        if k < 49 {
            let tm = t + 0.02;
            let p = pose(tm);
            for (i, l) in lms.iter().enumerate() {
                let (dx, dy) = (l[0] - p[0], l[1] - p[1]);
                let b = quarry_core::wrap_angle(dy.atan2(dx) - p[2]);
                let _ = writeln!(
                    meas,
                    "{:.3} {} {:.6} {:.6}",
                    t0 + tm,
                    60 + i,
                    dx.hypot(dy),
                    b
                );
            }
        }
    }
    let mut gt1 = h.to_string();
    for k in 0..=1100 {
        let t = 0.01 * f64::from(k) - 0.5;
        let p = pose(t);
        let _ = writeln!(gt1, "{:.3} {:.6} {:.6} {:.6}", t0 + t, p[0], p[1], p[2]);
    }
    let gt2 = format!("{h}990 20 20 0\n1020 20 20 0\n");
    vec![barcodes, landmarks, odo, meas, gt1, gt2]
}

/// Mean position error at the observation epochs, the tracker started on the true map.
fn synthetic_error(timing: quarry_data::mrclam::MeasurementTiming) -> f64 {
    use quarry_core::{Gaussian, LandmarkId};
    use quarry_data::mrclam::{MrclamTexts, from_texts_with};
    let t = synthetic_recording();
    let texts = MrclamTexts {
        barcodes: &t[0],
        landmarks: &t[1],
        odometry: &t[2],
        measurements: &t[3],
        groundtruth: vec![(1, &t[4]), (2, &t[5])],
    };
    let run = from_texts_with(&texts, 1, timing).unwrap();
    let prior: Vec<(LandmarkId, Gaussian<2>)> = run
        .landmarks
        .iter()
        .map(|(id, xy)| {
            (
                *id,
                Gaussian::try_new(
                    nalgebra::Vector2::new(xy[0], xy[1]),
                    nalgebra::Matrix2::identity() * 1e-4,
                )
                .unwrap(),
            )
        })
        .collect();
    let cfg = SlamotConfig {
        meas_noise: [0.05, 0.01],
        ..mrclam_config(100)
    };
    let mut tr = SlamotTracker::<quarry_trackers::slamot::DefaultStore>::with_prior_map(
        cfg,
        run.initial_pose,
        7,
        &prior,
    )
    .unwrap();
    let mut errs = Vec::new();
    for f in &run.frames {
        tr.step(
            Stamp::from_frame(f.k, f.dt),
            &quarry_repro::slamot::mrclam_observation(f),
        )
        .unwrap();
        if f.observe
            && let Some(tp) = f.truth.robot
        {
            let p = tr.pose_estimate();
            errs.push((p.x - tp.x).hypot(p.y - tp.y));
        }
    }
    assert!(errs.len() > 40);
    mean_var(&errs).0
}

#[test]
fn measurements_applied_at_their_own_stamp_do_not_bias_the_pose() {
    use quarry_data::mrclam::MeasurementTiming;
    let own = synthetic_error(MeasurementTiming::OwnStamp);
    let late = synthetic_error(MeasurementTiming::NextOdometry);
    eprintln!("synthetic arc: own stamp {own:.3} m, at the next odometry stamp {late:.3} m");
    assert!(own < 0.05, "own-stamp error {own}");
    assert!(late > 0.08, "late error {late}");
    assert!(own < 0.4 * late, "{own} vs {late}");
}

/// Mean position distance between two pose sequences of the same length.
fn mean_position_error(est: &[Pose2], truth: &[Pose2]) -> f64 {
    est.iter()
        .zip(truth)
        .map(|(a, b)| (a.x - b.x).hypot(a.y - b.y))
        .sum::<f64>()
        / truth.len() as f64
}

/// A recording whose odometry over-reads the turn rate by 8 % and leads the motion by 0.2 s (as
/// MRCLAM's does): the forward filter carries the error, the smoother removes it (with these
/// frequent sightings the plain smoother too: 0.03 m for both, the filter 0.22 m), and the
/// calibrated one recovers the scale and the lead.
#[test]
fn the_smoother_removes_a_miscalibrated_odometry_that_the_filter_carries() {
    use quarry_core::LandmarkId;
    use quarry_trackers::slamot::{SlamotObservation, smooth_run};
    let lms = [
        [3.0, 3.0],
        [-3.0, 3.0],
        [0.0, 6.0],
        [3.0, -1.0],
        [-3.0, -1.0],
    ];
    let cfg = SlamotConfig {
        meas_noise: [0.05, 0.01],
        ..mrclam_config(50)
    };
    let (dt, lead, scale) = (0.05, 0.2, 1.08);
    let w_true = |t: f64| 0.4 * (0.2 * t).sin();
    let mut pose = Pose2::identity();
    let mut obs = Vec::new();
    let mut truth = Vec::new();
    let mut rng = quarry_core::rng::seeded(5);
    let mut tr = SlamotTracker::new(cfg.clone(), Pose2::identity(), 3).unwrap();
    let mut guess = Vec::new();
    for k in 1..=1600u64 {
        let t = k as f64 * dt;
        pose = pose.compose(&Pose2::from_unicycle(0.4, w_true(t - 0.5 * dt), dt));
        let observe = k % 8 == 0;
        let mut landmark_obs = Vec::new();
        if observe {
            for (i, l) in lms.iter().enumerate() {
                let (dx, dy) = (l[0] - pose.x, l[1] - pose.y);
                let b = quarry_core::wrap_angle(dy.atan2(dx) - pose.theta);
                // a 90-degree camera
                if b.abs() < std::f64::consts::FRAC_PI_4 {
                    let nr: f64 = rand::Rng::sample(&mut rng, rand_distr::StandardNormal);
                    let nb: f64 = rand::Rng::sample(&mut rng, rand_distr::StandardNormal);
                    landmark_obs.push((
                        LandmarkId(i as u32),
                        [dx.hypot(dy) + 0.05 * nr, b + 0.01 * nb],
                    ));
                }
            }
        }
        // the record: the turn rate `lead` seconds ahead, over-read by `scale`
        let o = SlamotObservation {
            dt,
            odometry: (0.4, scale * w_true(t + lead - 0.5 * dt)),
            observe,
            landmark_obs,
            target_obs: vec![],
        };
        tr.step(Stamp::from_frame(k, dt), &o).unwrap();
        if observe {
            guess.push(tr.pose_estimate());
            truth.push(pose);
        }
        obs.push(o);
    }
    let err = |p: &[Pose2]| mean_position_error(p, &truth);
    let filter = err(&guess);
    let map = tr.map_estimate();
    let plain = smooth_run(&cfg, Pose2::identity(), &obs, Some(&guess), &map, false).unwrap();
    let cal = smooth_run(&cfg, Pose2::identity(), &obs, Some(&guess), &map, true).unwrap();
    let at_epochs = |s: &quarry_trackers::slamot::SmoothedRun| -> Vec<Pose2> {
        s.epoch_nodes.iter().map(|&n| s.result.poses[n]).collect()
    };
    let (e_plain, e_cal) = (err(&at_epochs(&plain)), err(&at_epochs(&cal)));
    let c = cal.result.calibration;
    eprintln!("filter {filter:.3} m, smoothed {e_plain:.3} m, calibrated {e_cal:.3} m, {c:?}");
    for e in [e_plain, e_cal] {
        assert!(e < 0.05, "smoother {e}");
        assert!(e < 0.3 * filter, "smoother {e} vs filter {filter}");
    }
    assert!((c.turn_scale - 1.0 / scale).abs() < 0.02, "{c:?}");
    assert!((c.time_offset - lead).abs() < 0.05, "{c:?}");
}

/// The smoother with the bicycle robot of the paper's S0 (the same model as the particles): over
/// three truth seeds the smoothed trajectory is closer to the truth than the filter's on average
/// (measured 0.306 / 0.301 / 0.310 m filter, 0.192 / 0.277 / 0.326 m smoothed: with a 360°
/// sensor and 49 landmarks the filter is already near its best, and one run is 5 % worse).
#[test]
fn smoothing_the_simulated_s0_run_lowers_the_robot_error() {
    use quarry_trackers::slamot::smooth_run;
    let scen = SlamotScenarioConfig::s0();
    let cfg = SlamotConfig::default();
    let (mut sum_f, mut sum_s) = (0.0, 0.0);
    for r in 0..3 {
        let frames = quarry_sim::slamot::simulate(&scen, r).unwrap();
        let [x, y, th] = scen.robot_init;
        let start = Pose2::new(x, y, th);
        let mut tr = SlamotTracker::new(cfg.clone(), start, filter_seed(r, 50)).unwrap();
        let (mut obs, mut guess, mut truth) = (Vec::new(), Vec::new(), Vec::new());
        for f in &frames {
            let o = observation(f);
            tr.step(Stamp::from_frame(f.k, scen.dt_control), &o)
                .unwrap();
            if o.observe {
                guess.push(tr.pose_estimate());
                truth.push(f.truth.robot);
            }
            obs.push(o);
        }
        let s = smooth_run(&cfg, start, &obs, Some(&guess), &tr.map_estimate(), false).unwrap();
        let err = |p: &[Pose2]| mean_position_error(p, &truth);
        let smoothed: Vec<Pose2> = s.epoch_nodes.iter().map(|&n| s.result.poses[n]).collect();
        let (ef, es) = (err(&guess), err(&smoothed));
        eprintln!("S0 run {r}: filter {ef:.3} m, smoothed {es:.3} m");
        assert!(s.result.converged);
        assert!(es < 1.1 * ef, "run {r}: smoothed {es} vs filter {ef}");
        sum_f += ef;
        sum_s += es;
    }
    assert!(
        sum_s < 0.95 * sum_f,
        "smoothed {sum_s} vs filter {sum_f} (sums over 3 runs)"
    );
}
