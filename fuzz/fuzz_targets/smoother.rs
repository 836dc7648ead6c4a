//! Drives the batch smoother (`quarry_filter::smoother::smooth`) and the SLAMOT wrapper
//! (`quarry_trackers::slamot::smooth_run`) with arbitrary small problems: node times, odometry,
//! detections, guesses and settings, possibly non-finite, out of order or out of range. It must
//! answer or refuse, never panic or hang.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::{LandmarkId, Pose2};
use quarry_filter::smoother::{
    CalibrationPrior, LandmarkObservation, OdometryStep, SmootherConfig, SmootherProblem, smooth,
};
use quarry_trackers::slamot::{SlamotConfig, SlamotObservation, smooth_run};

#[path = "common/floats.rs"]
mod common_floats;
use common_floats::floats;

fuzz_target!(|data: &[u8]| {
    let Some((&head, rest)) = data.split_first() else {
        return;
    };
    let mut it = floats(rest).chain(std::iter::repeat(0.5));
    let mut next = || it.next().unwrap_or(0.0);
    let n_nodes = usize::from(head & 7);
    let n_steps = usize::from((head >> 3) & 7);
    let n_obs = usize::from(head >> 6) * 3;
    let problem = SmootherProblem {
        prior: Pose2 {
            x: next(),
            y: next(),
            theta: next(),
        },
        steps: (0..n_steps)
            .map(|_| OdometryStep {
                t_end: next(),
                dt: next(),
                control: (next(), next()),
            })
            .collect(),
        node_times: (0..n_nodes).map(|_| next()).collect(),
        observations: (0..n_obs)
            .map(|_| LandmarkObservation {
                node: (next().abs() * 8.0) as usize,
                landmark: LandmarkId((next().abs() * 4.0) as u32),
                range: next(),
                bearing: next(),
            })
            .collect(),
        initial_poses: if head & 1 == 1 {
            Some(
                (0..n_nodes)
                    .map(|_| Pose2 {
                        x: next(),
                        y: next(),
                        theta: next(),
                    })
                    .collect(),
            )
        } else {
            None
        },
        initial_landmarks: vec![(LandmarkId(0), [next(), next()])],
    };
    for calibration in [CalibrationPrior::NONE, CalibrationPrior::WEAK] {
        let cfg = SmootherConfig {
            sigma_range: next(),
            calibration,
            max_iterations: 30,
            ..SmootherConfig::default()
        };
        let _ = smooth(&problem, &cfg);
    }
    // the SLAMOT wrapper over the same numbers
    let obs: Vec<SlamotObservation> = (0..n_steps + n_nodes)
        .map(|k| SlamotObservation {
            dt: next(),
            odometry: (next(), next()),
            observe: k % 2 == 0,
            landmark_obs: vec![(LandmarkId(k as u32 % 3), [next(), next()])],
            target_obs: vec![],
        })
        .collect();
    let cfg = SlamotConfig::mrclam();
    let _ = smooth_run(&cfg, Pose2::identity(), &obs, None, &[], head & 2 == 2);
});
