//! SIFT keypoints in two images and their ratio-test matches.
//!
//! `cargo run --release --example sift_match [IMAGE1 IMAGE2]` (defaults: the bench-data pair
//! `photo_gray.png` / `sift_rot30_s0.8.png` from `../shared`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::core::FeatureExtractor;
use quarry::vision::io::load_gray;
use quarry::vision::matching::{BruteForceL2, MatchOptions, match_descriptors};
use quarry::vision::sift::Sift;
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (a, b) = if args.len() == 2 {
        (PathBuf::from(&args[0]), PathBuf::from(&args[1]))
    } else {
        let dir = std::env::var_os("QUARRY_SHARED").map_or_else(
            || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
            PathBuf::from,
        );
        let dir = dir.join("bench-data");
        if !dir.join("photo_gray.png").exists() {
            eprintln!(
                "usage: sift_match IMAGE1 IMAGE2 (no bench-data at {})",
                dir.display()
            );
            return;
        }
        (dir.join("photo_gray.png"), dir.join("sift_rot30_s0.8.png"))
    };
    let sift = Sift::default(); // OpenCV's defaults: 3 layers, sigma 1.6, up-sampled octave -1
    let (k1, d1) = sift.detect_and_compute(&load_gray(&a).unwrap()).unwrap();
    let (k2, d2) = sift.detect_and_compute(&load_gray(&b).unwrap()).unwrap();
    println!(
        "{}: {} keypoints, {}: {} keypoints",
        a.display(),
        k1.len(),
        b.display(),
        k2.len()
    );

    // Lowe's ratio test (0.8) plus the mutual check.
    let opts = MatchOptions {
        ratio: Some(0.8),
        max_distance: None,
        mutual: true,
    };
    let matches = match_descriptors(&BruteForceL2, &d1, &d2, &opts);
    println!(
        "{} mutual ratio-test matches; the five closest:",
        matches.len()
    );
    let mut best = matches.clone();
    best.sort_by(|x, y| x.distance.total_cmp(&y.distance));
    for m in best.iter().take(5) {
        let (p, q) = (&k1[m.query], &k2[m.train]);
        println!(
            "  ({:7.2}, {:7.2}) sigma {:5.2} -> ({:7.2}, {:7.2}) sigma {:5.2}   L2 {:6.1}",
            p.x, p.y, p.sigma, q.x, q.y, q.sigma, m.distance
        );
    }
}
