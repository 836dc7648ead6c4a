//! Fuzz the background calibration (spec 003 §2.3): arbitrary background ranges (NaN, inf,
//! negative, huge), rough poses and parameters through `background_points`,
//! `free_space_violations`, `register_background` and `calibrate`: results or typed errors,
//! never a panic; every accepted pose is finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_cloud::calib::{
    CalibConfig, ScannerBackground, background_points, calibrate, free_space_violations,
};
use quarry_core::{Pose2, ScanGeometry, SensorId};

fn f64s(data: &[u8]) -> impl Iterator<Item = f64> + '_ {
    data.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
}

fuzz_target!(|data: &[u8]| {
    let g = ScanGeometry {
        n_beams: 64,
        angle_min: -1.6,
        angle_increment: 0.05,
        range_min: 0.02,
        range_max: 30.0,
        scan_period: 0.025,
    };
    let (head, rest) = data.split_at(data.len().min(6 * 8 + 2));
    let mut nums = f64s(head);
    let mut pose = || {
        let mut n = || nums.next().unwrap_or(0.0);
        Pose2::new(n(), n(), n())
    };
    let (p_ref, p_other) = (pose(), pose());
    let flags = head.get(48..).unwrap_or(&[]);
    let cfg = CalibConfig {
        point_to_line: flags.first().is_some_and(|b| b & 1 == 1),
        ..CalibConfig::default()
    };
    // two backgrounds from the rest: 8 bytes per beam, cycled if short
    let ranges: Vec<f64> = f64s(rest).collect();
    let bg = |off: usize| -> Vec<Option<f64>> {
        (0..g.n_beams as usize)
            .map(|n| {
                if ranges.is_empty() {
                    return None;
                }
                let r = ranges[(n + off) % ranges.len()];
                (r.to_bits() & 1 == 0).then_some(r.abs() % 40.0)
            })
            .collect()
    };
    let (b0, b1) = (bg(0), bg(7));
    let Ok(pts0) = background_points(&b0, &g, cfg.max_background_range) else {
        return;
    };
    let Ok(pts1) = background_points(&b1, &g, cfg.max_background_range) else {
        return;
    };
    let _ = free_space_violations(&pts0, &p_other, &b1, &g, 0.15);
    let _ = background_points(&b0[..b0.len() / 2], &g, 28.5); // wrong length: an error
    let reference = ScannerBackground {
        sensor: SensorId(0),
        points: pts0,
        pose: p_ref,
    };
    let other = ScannerBackground {
        sensor: SensorId(1),
        points: pts1,
        pose: p_other,
    };
    if let Ok(res) = calibrate(&cfg, &reference, &[other]) {
        for r in res {
            assert!(r.pose.is_finite(), "{r:?}");
        }
    }
});
