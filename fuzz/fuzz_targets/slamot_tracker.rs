//! Drives the SLAMOT tracker (`quarry_trackers::slamot::SlamotTracker`, the RBPF) and the
//! EKF-SLAMOT baseline with arbitrary short observation sequences under each preset: step
//! lengths, odometry, landmark and target detections, possibly non-finite, zero, negative or
//! huge. Each step must answer or refuse, never panic or hang; an accepted step leaves finite
//! estimates and existences in [0, 1].
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::{LandmarkId, MultiTargetTracker, Pose2, Stamp};
use quarry_trackers::TrackerConfig;
use quarry_trackers::ekf_slamot::EkfSlamot;
use quarry_trackers::slamot::{Preset, SlamotConfig, SlamotObservation, SlamotTracker};

#[path = "common/floats.rs"]
mod common_floats;
use common_floats::floats;

fuzz_target!(|data: &[u8]| {
    let Some((&head, rest)) = data.split_first() else {
        return;
    };
    let preset = [Preset::Paper, Preset::S1, Preset::Mrclam][usize::from(head % 3)];
    let cfg = SlamotConfig {
        particles: 4,
        ..SlamotConfig::preset(preset)
    };
    let Ok(mut rbpf) = SlamotTracker::new(cfg.clone(), Pose2::identity(), u64::from(head)) else {
        return;
    };
    let mut ekf = EkfSlamot::new(cfg, Pose2::identity()).ok();
    // per step: a control byte, then floats
    let mut bytes = rest.chunks(8 * 12);
    for k in 0..16u64 {
        let Some(chunk) = bytes.next() else { break };
        let ctl = chunk.first().copied().unwrap_or(0);
        let mut it = floats(chunk).chain(std::iter::repeat(1.0));
        let mut next = || it.next().unwrap_or(0.0);
        let obs = SlamotObservation {
            dt: next(),
            odometry: (next(), next()),
            observe: ctl & 1 == 1,
            landmark_obs: (0..usize::from((ctl >> 1) & 3))
                .map(|i| (LandmarkId(i as u32 + u32::from(ctl >> 6)), [next(), next()]))
                .collect(),
            target_obs: (0..usize::from((ctl >> 3) & 3))
                .map(|_| [next(), next()])
                .collect(),
        };
        let stamp = Stamp::from_frame(k + 1, 0.1);
        if rbpf.step(stamp, &obs).is_ok() {
            let p = rbpf.pose_estimate();
            assert!(p.x.is_finite() && p.y.is_finite() && p.theta.is_finite());
            for (_, g, psi) in rbpf.target_estimates() {
                assert!((0.0..=1.0).contains(psi));
                assert!(g.mean.iter().all(|v| v.is_finite()));
            }
        }
        if let Some(e) = ekf.as_mut() {
            let _ = e.step(stamp, &obs);
        }
    }
});
