//! The batch smoother (`quarry_filter::smoother`): exact recovery on noise-free data, recovery of
//! a known odometry calibration, robustness to a gross outlier, rigid-motion equivariance, a cost
//! that never rises, and clear errors on bad input.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use proptest::prelude::*;
use quarry_core::{LandmarkId, Pose2, wrap_angle};
use quarry_filter::FilterError;
use quarry_filter::smoother::{
    Calibration, CalibrationPrior, LandmarkObservation, MAX_LANDMARKS, OdometryStep,
    SmootherConfig, SmootherProblem, smooth,
};
use rand::Rng;
use rand_distr::StandardNormal;

/// The true controls at time t of the test drive: 0.5 m/s, a slowly varying turn rate.
fn controls(t: f64) -> (f64, f64) {
    (0.5, 0.35 * (0.13 * t).sin() + 0.1)
}

const LANDMARKS: [[f64; 2]; 9] = [
    [2.0, 2.0],
    [5.0, -1.0],
    [-2.0, 4.0],
    [0.0, 7.0],
    [6.0, 5.0],
    [-4.0, 0.0],
    [3.0, 9.0],
    [-1.0, -3.0],
    [8.0, 1.0],
];

struct Drive {
    problem: SmootherProblem,
    truth: Vec<Pose2>,
}

/// A 60-s drive from `start`: odometry every 0.05 s, a node every 0.5 s seeing every landmark
/// within 6 m. `record` maps a true (t_end, dt, v, ω) to the recorded step; `noise` (σ_r, σ_b)
/// perturbs the detections with a seeded generator.
fn drive(start: Pose2, noise: Option<(f64, f64, u64)>, calib: Calibration) -> Drive {
    let dt = 0.05;
    let mut rng = quarry_core::rng::seeded(noise.map_or(0, |n| n.2));
    let mut pose = start;
    let mut truth = vec![start];
    let mut node_times = vec![0.0];
    let mut steps = Vec::new();
    let mut observations = Vec::new();
    let landmarks: Vec<[f64; 2]> = LANDMARKS
        .iter()
        .map(|m| {
            let p = start.apply(&quarry_core::Point2::new(m[0], m[1]));
            [p.x, p.y]
        })
        .collect();
    for k in 1..=1200 {
        let t = k as f64 * dt;
        let (v, w) = controls(t - 0.5 * dt);
        pose = pose.compose(&Pose2::from_unicycle(v, w, dt));
        // the record: the controls as a miscalibrated odometry reports them, stamped
        // `time_offset` early
        steps.push(OdometryStep {
            t_end: t - calib.time_offset,
            dt,
            control: (
                v / calib.speed_scale,
                (w - calib.turn_bias) / calib.turn_scale,
            ),
        });
        if k % 10 == 0 {
            let node = node_times.len();
            node_times.push(t);
            truth.push(pose);
            for (l, m) in landmarks.iter().enumerate() {
                let (dx, dy) = (m[0] - pose.x, m[1] - pose.y);
                let r = dx.hypot(dy);
                if r > 6.0 {
                    continue;
                }
                let mut b = wrap_angle(dy.atan2(dx) - pose.theta);
                let mut rr = r;
                if let Some((sr, sb, _)) = noise {
                    rr += sr * rng.sample::<f64, _>(StandardNormal);
                    b += sb * rng.sample::<f64, _>(StandardNormal);
                }
                observations.push(LandmarkObservation {
                    node,
                    landmark: LandmarkId(l as u32),
                    range: rr,
                    bearing: b,
                });
            }
        }
    }
    Drive {
        problem: SmootherProblem {
            prior: start,
            steps,
            node_times,
            observations,
            initial_poses: None,
            initial_landmarks: vec![],
        },
        truth,
    }
}

fn max_pos_err(a: &[Pose2], b: &[Pose2]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p.x - q.x).hypot(p.y - q.y))
        .fold(0.0, f64::max)
}

#[test]
fn noise_free_data_are_recovered_exactly_from_a_perturbed_start() {
    let mut d = drive(Pose2::new(1.0, -2.0, 0.4), None, Calibration::IDENTITY);
    // start 0.3 m and 0.05 rad off everywhere, landmarks 0.4 m off
    d.problem.initial_poses = Some(
        d.truth
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let s = (i as f64 * 0.7).sin();
                Pose2::new(p.x + 0.3 * s, p.y - 0.3 * s, p.theta + 0.05 * s)
            })
            .collect(),
    );
    d.problem.initial_landmarks = (0..LANDMARKS.len())
        .map(|l| {
            let m = d.truth[0].apply(&quarry_core::Point2::new(LANDMARKS[l][0], LANDMARKS[l][1]));
            (LandmarkId(l as u32), [m.x + 0.4, m.y - 0.4])
        })
        .collect();
    let out = smooth(&d.problem, &SmootherConfig::default()).unwrap();
    assert!(out.converged);
    assert!(out.final_cost < 1e-6 * out.initial_cost.max(1.0), "{out:?}");
    assert!(max_pos_err(&out.poses, &d.truth) < 1e-5);
    for (p, q) in out.poses.iter().zip(&d.truth) {
        assert!(wrap_angle(p.theta - q.theta).abs() < 1e-6);
    }
    for (id, m) in &out.landmarks {
        let t = d.truth[0].apply(&quarry_core::Point2::new(
            LANDMARKS[id.0 as usize][0],
            LANDMARKS[id.0 as usize][1],
        ));
        assert!((m[0] - t.x).hypot(m[1] - t.y) < 1e-5);
    }
    assert_eq!(out.downweighted, 0);
}

#[test]
fn a_known_odometry_miscalibration_is_recovered_and_matters() {
    let truth_cal = Calibration {
        speed_scale: 0.95,
        turn_scale: 0.92,
        turn_bias: -0.01,
        time_offset: 0.2,
    };
    let d = drive(Pose2::identity(), Some((0.02, 0.005, 7)), truth_cal);
    let cfg = SmootherConfig {
        sigma_range: 0.02,
        sigma_bearing: 0.005,
        ..SmootherConfig::default()
    };
    let cal = smooth(
        &d.problem,
        &SmootherConfig {
            calibration: CalibrationPrior::WEAK,
            ..cfg
        },
    )
    .unwrap();
    let c = cal.calibration;
    assert!((c.speed_scale - 0.95).abs() < 0.01, "{c:?}");
    assert!((c.turn_scale - 0.92).abs() < 0.01, "{c:?}");
    assert!((c.turn_bias + 0.01).abs() < 0.003, "{c:?}");
    assert!((c.time_offset - 0.2).abs() < 0.03, "{c:?}");
    let plain = smooth(&d.problem, &cfg).unwrap();
    assert_eq!(plain.calibration, Calibration::IDENTITY);
    let mean = |p: &[Pose2]| {
        p.iter()
            .zip(&d.truth)
            .map(|(a, b)| (a.x - b.x).hypot(a.y - b.y))
            .sum::<f64>()
            / p.len() as f64
    };
    let (e_cal, e_plain) = (mean(&cal.poses), mean(&plain.poses));
    assert!(e_cal < 0.02, "calibrated {e_cal}");
    assert!(
        e_plain > 2.0 * e_cal,
        "plain {e_plain} vs calibrated {e_cal}"
    );
}

#[test]
fn a_gross_bearing_outlier_is_downweighted_by_the_huber_loss() {
    let mut d = drive(
        Pose2::identity(),
        Some((0.02, 0.005, 3)),
        Calibration::IDENTITY,
    );
    // a bearing off by pi at a node in the middle (as MRCLAM has a few)
    let k = d.problem.observations.len() / 2;
    d.problem.observations[k].bearing = wrap_angle(d.problem.observations[k].bearing + 3.1);
    let cfg = SmootherConfig {
        sigma_range: 0.02,
        sigma_bearing: 0.005,
        ..SmootherConfig::default()
    };
    let huber = smooth(&d.problem, &cfg).unwrap();
    let ls = smooth(
        &d.problem,
        &SmootherConfig {
            huber_k: None,
            ..cfg
        },
    )
    .unwrap();
    let (eh, el) = (
        max_pos_err(&huber.poses, &d.truth),
        max_pos_err(&ls.poses, &d.truth),
    );
    assert!(eh < 0.05, "huber max error {eh}");
    assert!(el > 2.0 * eh, "least squares {el} vs huber {eh}");
    assert!(huber.downweighted >= 1);
}

#[test]
fn dead_reckoning_start_without_guesses_converges() {
    let d = drive(
        Pose2::new(-3.0, 2.0, 2.0),
        Some((0.02, 0.005, 11)),
        Calibration::IDENTITY,
    );
    let out = smooth(
        &d.problem,
        &SmootherConfig {
            sigma_range: 0.02,
            sigma_bearing: 0.005,
            ..SmootherConfig::default()
        },
    )
    .unwrap();
    assert!(out.converged);
    assert!(max_pos_err(&out.poses, &d.truth) < 0.05);
    assert_eq!(out.landmarks.len(), LANDMARKS.len());
}

fn tiny() -> SmootherProblem {
    SmootherProblem {
        prior: Pose2::identity(),
        steps: vec![OdometryStep {
            t_end: 1.0,
            dt: 1.0,
            control: (1.0, 0.0),
        }],
        node_times: vec![0.0, 1.0],
        observations: vec![LandmarkObservation {
            node: 1,
            landmark: LandmarkId(0),
            range: 1.0,
            bearing: 0.0,
        }],
        initial_poses: None,
        initial_landmarks: vec![],
    }
}

#[test]
fn bad_input_is_a_clear_error() {
    let cfg = SmootherConfig::default();
    assert!(smooth(&tiny(), &cfg).is_ok());
    let cases: Vec<(SmootherProblem, &str)> = vec![
        (
            SmootherProblem {
                node_times: vec![],
                observations: vec![],
                ..tiny()
            },
            "empty",
        ),
        (
            SmootherProblem {
                node_times: vec![0.0, 0.0],
                ..tiny()
            },
            "is not after",
        ),
        (
            SmootherProblem {
                node_times: vec![0.0, f64::NAN],
                ..tiny()
            },
            "node time",
        ),
        (
            {
                let mut p = tiny();
                p.observations[0].range = f64::NAN;
                p
            },
            "non-finite",
        ),
        (
            {
                let mut p = tiny();
                p.observations[0].range = -1.0;
                p
            },
            "<= 0",
        ),
        (
            {
                let mut p = tiny();
                p.observations[0].node = 5;
                p
            },
            "node 5 of 2",
        ),
        (
            {
                let mut p = tiny();
                p.steps[0].dt = -1.0;
                p
            },
            "dt",
        ),
        (
            {
                let mut p = tiny();
                p.steps.push(p.steps[0]);
                p
            },
            "before the previous step ends",
        ),
        (
            SmootherProblem {
                initial_poses: Some(vec![Pose2::identity()]),
                ..tiny()
            },
            "initial poses",
        ),
        (
            SmootherProblem {
                prior: Pose2 {
                    x: f64::INFINITY,
                    y: 0.0,
                    theta: 0.0,
                },
                ..tiny()
            },
            "prior",
        ),
        (
            SmootherProblem {
                observations: one_sighting_each(MAX_LANDMARKS as u32 + 1),
                ..tiny()
            },
            "distinct landmarks",
        ),
        (
            // 200 000 nodes x 100 landmarks: a 122-million-entry border, refused
            SmootherProblem {
                node_times: (0..200_000).map(f64::from).collect(),
                observations: one_sighting_each(100),
                ..tiny()
            },
            "dense border",
        ),
    ];
    for (p, needle) in cases {
        let e = smooth(&p, &cfg).unwrap_err().to_string();
        assert!(e.contains(needle), "{e:?} should contain {needle:?}");
    }
    for bad in [
        SmootherConfig {
            control_sigma: [0.0, 0.1],
            ..cfg
        },
        SmootherConfig {
            sigma_bearing: f64::NAN,
            ..cfg
        },
        SmootherConfig {
            huber_k: Some(-1.0),
            ..cfg
        },
        SmootherConfig {
            max_iterations: usize::MAX,
            ..cfg
        },
        SmootherConfig {
            calibration: CalibrationPrior {
                time_offset: Some(0.0),
                ..CalibrationPrior::NONE
            },
            ..cfg
        },
    ] {
        assert!(matches!(smooth(&tiny(), &bad), Err(FilterError::Core(_))));
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Moving the whole problem by a rigid transform (the prior and the starting guesses) moves
    /// the solution by the same transform, and the cost never rises.
    #[test]
    fn rigid_motion_equivariance_and_a_falling_cost(
        x in -20.0..20.0f64, y in -20.0..20.0f64, th in -3.1..3.1f64, seed in 0u64..1000
    ) {
        let d = drive(Pose2::identity(), Some((0.05, 0.01, seed)), Calibration::IDENTITY);
        // tolerance 0: iterate until no step lowers the cost, so that both solutions are the
        // optimum to working precision (LM's damping is not rotation-invariant, so the paths
        // differ)
        let cfg = SmootherConfig { sigma_range: 0.05, tolerance: 0.0, ..SmootherConfig::default() };
        let a = smooth(&d.problem, &cfg).unwrap();
        prop_assert!(a.final_cost <= a.initial_cost);
        let t = Pose2::new(x, y, th);
        let mut moved = d.problem.clone();
        moved.prior = t.compose(&d.problem.prior);
        let b = smooth(&moved, &cfg).unwrap();
        prop_assert!(b.final_cost <= b.initial_cost);
        for (p, q) in a.poses.iter().zip(&b.poses) {
            let pm = t.compose(p);
            prop_assert!((pm.x - q.x).hypot(pm.y - q.y) < 1e-6);
            prop_assert!(wrap_angle(pm.theta - q.theta).abs() < 1e-7);
        }
        for ((ia, ma), (ib, mb)) in a.landmarks.iter().zip(&b.landmarks) {
            prop_assert_eq!(ia, ib);
            let m = t.apply(&quarry_core::Point2::new(ma[0], ma[1]));
            prop_assert!((m.x - mb[0]).hypot(m.y - mb[1]) < 1e-6);
        }
    }

    /// Arbitrary small problems: an answer or an error, never a panic; an answer is finite.
    #[test]
    fn arbitrary_small_problems_never_panic(
        times in prop::collection::vec(-5.0..5.0f64, 0..6),
        steps in prop::collection::vec((-5.0..5.0f64, -1.0..2.0f64, -3.0..3.0f64, -5.0..5.0f64), 0..8),
        obs in prop::collection::vec((0usize..7, 0u32..4, -1.0..10.0f64, -4.0..4.0f64), 0..10),
        cal in any::<bool>(),
    ) {
        let p = SmootherProblem {
            prior: Pose2::identity(),
            steps: steps.iter().map(|&(t, dt, v, w)| OdometryStep { t_end: t, dt, control: (v, w) }).collect(),
            node_times: times,
            observations: obs.iter().map(|&(node, l, r, b)| LandmarkObservation {
                node, landmark: LandmarkId(l), range: r, bearing: b,
            }).collect(),
            initial_poses: None,
            initial_landmarks: vec![],
        };
        let cfg = SmootherConfig {
            calibration: if cal { CalibrationPrior::WEAK } else { CalibrationPrior::NONE },
            max_iterations: 20,
            ..SmootherConfig::default()
        };
        if let Ok(out) = smooth(&p, &cfg) {
            prop_assert!(out.poses.iter().all(Pose2::is_finite));
            prop_assert!(out.landmarks.iter().all(|(_, m)| m[0].is_finite() && m[1].is_finite()));
            prop_assert!(out.final_cost <= out.initial_cost);
        }
    }
}

/// One detection (1 m straight ahead, from node 1) of each of landmarks 0..n.
fn one_sighting_each(n: u32) -> Vec<LandmarkObservation> {
    (0..n)
        .map(|l| LandmarkObservation {
            node: 1,
            landmark: LandmarkId(l),
            range: 1.0,
            bearing: 0.0,
        })
        .collect()
}
