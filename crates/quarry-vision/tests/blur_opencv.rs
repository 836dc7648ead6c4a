//! Agreement of the blur with `cv2.GaussianBlur` (fixtures from `fixtures/blur/dump_opencv_blur.py`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry_core::Plane;
use quarry_vision::{gaussian_blur_f32, gaussian_blur_f64};
use std::path::PathBuf;

fn fixture(name: &str) -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/blur")
        .join(name);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn synth(w: u32, h: u32) -> Plane<f64> {
    Plane::from_fn(w, h, |x, y| {
        let (xf, yf) = (f64::from(x), f64::from(y));
        f64::from((37 * x + 11 * y + 5 * x * y) % 256) + 0.25 * (xf + 2.0 * yf).sin()
    })
}

const CASES: [(u32, u32, f64, &str); 4] = [
    (29, 23, 1.5, "1.5"),
    (29, 23, 3.0, "3"),
    (31, 9, 5.0, "5"),
    (7, 1, 0.8, "0.8"),
];

#[test]
fn small_images_match_opencv_f64() {
    for (w, h, sigma, tag) in CASES {
        let expected: Vec<f64> = fixture(&format!("small_f64_s{tag}_{w}x{h}.csv"))
            .lines()
            .map(|l| l.parse().unwrap())
            .collect();
        let got = gaussian_blur_f64(&synth(w, h), sigma).unwrap();
        assert_eq!(got.data.len(), expected.len());
        let max = got
            .data
            .iter()
            .zip(&expected)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(max < 1e-9, "sigma {sigma} {w}x{h}: max diff {max}");
    }
}

#[test]
fn small_images_match_opencv_f32() {
    for (w, h, sigma, tag) in CASES {
        let expected: Vec<f64> = fixture(&format!("small_f32_s{tag}_{w}x{h}.csv"))
            .lines()
            .map(|l| l.parse().unwrap())
            .collect();
        let src = synth(w, h).map(|&v| v as f32);
        let got = gaussian_blur_f32(&src, sigma).unwrap();
        let max = got
            .data
            .iter()
            .zip(&expected)
            .map(|(a, b)| (f64::from(*a) - b).abs())
            .fold(0.0, f64::max);
        assert!(max < 1e-4, "sigma {sigma} {w}x{h}: max diff {max}");
    }
}

fn shared() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
        PathBuf::from,
    );
    if p.join("bench-data/photo_gray.png").exists() {
        Some(p)
    } else {
        eprintln!("skipping: shared data not found at {}", p.display());
        None
    }
}

#[test]
fn photo_sigma8_matches_opencv() {
    let Some(sh) = shared() else { return };
    let gray = quarry_vision::io::load_gray(sh.join("bench-data/photo_gray.png")).unwrap();
    assert_eq!(gray.dimensions(), (800, 450));
    let b64 = gaussian_blur_f64(&gray.map(|&v| f64::from(v)), 8.0).unwrap();
    let b32 = gaussian_blur_f32(&gray.map(|&v| f32::from(v)), 8.0).unwrap();
    for (name, tol) in [("f64", 1e-9), ("f32", 1e-4)] {
        let text = fixture(&format!("photo_{name}_s8_samples.csv"));
        let mut n = 0;
        for line in text.lines() {
            let f: Vec<&str> = line.split(',').collect();
            if f[0] == "mean" {
                let m: f64 = f[1].parse().unwrap();
                let got = if name == "f64" {
                    b64.data.iter().sum::<f64>() / b64.len() as f64
                } else {
                    b32.data.iter().map(|&v| f64::from(v)).sum::<f64>() / b32.len() as f64
                };
                assert!((got - m).abs() < tol, "{name} mean {got} vs {m}");
                continue;
            }
            let (x, y, v): (u32, u32, f64) = (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
            );
            let got = if name == "f64" {
                *b64.get(x, y).unwrap()
            } else {
                f64::from(*b32.get(x, y).unwrap())
            };
            assert!((got - v).abs() < tol, "{name} ({x},{y}): {got} vs {v}");
            n += 1;
        }
        assert_eq!(n, 60);
    }
}
