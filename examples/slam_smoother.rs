//! Batch smoothing of a landmark-SLAM recording: a robot whose odometry over-reads its turn rate
//! by 8 % drives a loop past six landmarks; dead reckoning drifts, the smoother puts every pose
//! and landmark back and estimates the odometry's calibration.
//!
//! `cargo run --example slam_smoother`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::core::{LandmarkId, Pose2, rng::seeded, wrap_angle};
use quarry::filter::smoother::{
    CalibrationPrior, LandmarkObservation, OdometryStep, SmootherConfig, SmootherProblem, smooth,
};
use rand::Rng;
use rand_distr::StandardNormal;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let landmarks = [
        [4.0, 0.0],
        [8.0, 4.0],
        [4.0, 8.0],
        [0.0, 4.0],
        [6.0, 6.0],
        [2.0, 2.0],
    ];
    let mut rng = seeded(4);
    let (dt, v) = (0.05, 0.5);
    let mut pose = Pose2::identity();
    let (mut steps, mut node_times, mut observations, mut truth) =
        (Vec::new(), vec![0.0], Vec::new(), vec![pose]);
    for k in 1..=1600 {
        let t = f64::from(k) * dt;
        // a varying turn rate (with a constant one a scale and a bias could not be told apart)
        let w = 0.12 + 0.1 * (0.2 * t).sin();
        pose = pose.compose(&Pose2::from_unicycle(v, w, dt));
        // the odometry reports 8 % more turn than the robot made
        steps.push(OdometryStep {
            t_end: t,
            dt,
            control: (v, 1.08 * w),
        });
        if k % 10 == 0 {
            node_times.push(t);
            truth.push(pose);
            for (l, m) in landmarks.iter().enumerate() {
                let (dx, dy) = (m[0] - pose.x, m[1] - pose.y);
                let bearing = wrap_angle(dy.atan2(dx) - pose.theta);
                if dx.hypot(dy) < 5.0 && bearing.abs() < 1.0 {
                    observations.push(LandmarkObservation {
                        node: node_times.len() - 1,
                        landmark: LandmarkId(l as u32),
                        range: dx.hypot(dy) + 0.03 * rng.sample::<f64, _>(StandardNormal),
                        bearing: bearing + 0.01 * rng.sample::<f64, _>(StandardNormal),
                    });
                }
            }
        }
    }
    let problem = SmootherProblem {
        prior: Pose2::identity(),
        steps,
        node_times,
        observations,
        initial_poses: None, // start from dead reckoning
        initial_landmarks: vec![],
    };
    let cfg = SmootherConfig {
        sigma_range: 0.03,
        sigma_bearing: 0.01,
        calibration: CalibrationPrior::WEAK,
        ..SmootherConfig::default()
    };
    let out = smooth(&problem, &cfg)?;
    let err = |p: &Pose2, q: &Pose2| (p.x - q.x).hypot(p.y - q.y);
    let mut dead = Pose2::identity();
    let mut worst_dr = 0.0_f64;
    for (i, s) in problem.steps.iter().enumerate() {
        dead = dead.compose(&Pose2::from_unicycle(s.control.0, s.control.1, s.dt));
        if (i + 1) % 10 == 0 {
            worst_dr = worst_dr.max(err(&dead, &truth[(i + 1) / 10]));
        }
    }
    let worst = out
        .poses
        .iter()
        .zip(&truth)
        .map(|(p, q)| err(p, q))
        .fold(0.0, f64::max);
    println!("dead reckoning: worst position error {worst_dr:.2} m");
    println!(
        "smoothed ({} iterations): worst position error {worst:.3} m, turn-rate scale {:.3} (truth {:.3}), bias {:.4} rad/s",
        out.iterations,
        out.calibration.turn_scale,
        1.0 / 1.08,
        out.calibration.turn_bias
    );
    for (id, m) in &out.landmarks {
        let t = landmarks[id.0 as usize];
        println!(
            "landmark {}: ({:.2}, {:.2}), error {:.3} m",
            id.0,
            m[0],
            m[1],
            (m[0] - t[0]).hypot(m[1] - t[1])
        );
    }
    assert!(worst < 0.2 && worst_dr > 1.0);
    Ok(())
}
