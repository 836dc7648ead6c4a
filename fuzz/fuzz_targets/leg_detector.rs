//! quarry-cloud's leg detector (`legs::LegDetector`) on arbitrary points (NaN, inf, huge,
//! coincident) and parameters: errors are fine, panics are not; accepted detections are
//! finite, lie within the points' bounding box, and use each point at most once.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_cloud::legs::LegDetector;
use quarry_core::Point2;

fn f64_at(data: &[u8], i: usize) -> f64 {
    let mut b = [0u8; 8];
    for (k, x) in b.iter_mut().enumerate() {
        *x = data.get(i * 8 + k).copied().unwrap_or(0);
    }
    match b[7] % 4 {
        0 => f64::from_le_bytes(b),
        _ => f64::from(i16::from_le_bytes([b[0], b[1]])) / 1000.0,
    }
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 5 {
        return;
    }
    let d = LegDetector {
        cluster_dist: f64::from(data[0]) / 255.0 * 0.5,
        min_points: usize::from(data[1] % 8),
        max_width: f64::from(data[2]) / 255.0,
        max_pair_dist: f64::from(data[3]) / 100.0,
        single_legs: data[4] % 2 == 0,
    };
    let rest = &data[5..];
    let pts: Vec<Point2> = (0..rest.len() / 16)
        .map(|i| Point2::new(f64_at(rest, 2 * i), f64_at(rest, 2 * i + 1)))
        .collect();
    let Ok(people) = d.detect(&pts) else {
        return;
    };
    let support: usize = people.iter().map(|p| p.support).sum();
    assert!(support <= pts.len());
    let (x0, x1) = pts
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.x), b.max(p.x))
        });
    let (y0, y1) = pts
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.y), b.max(p.y))
        });
    for p in &people {
        assert!(
            p.position.x.is_finite() && p.position.y.is_finite(),
            "{p:?}"
        );
        let tol = 1e-9 * (1.0 + x1.abs().max(x0.abs()).max(y1.abs()).max(y0.abs()));
        assert!(
            p.position.x >= x0 - tol && p.position.x <= x1 + tol,
            "{p:?}"
        );
        assert!(
            p.position.y >= y0 - tol && p.position.y <= y1 + tol,
            "{p:?}"
        );
    }
});
