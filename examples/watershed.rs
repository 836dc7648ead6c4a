//! Watershed segmentation of one frame (spec 004: ramp → f64 Gaussian blur → regional minima →
//! Meyer flooding), its region adjacency and statistics, and the region mapping onto a second
//! frame.
//!
//! `cargo run --release --example watershed [IMAGE [SIGMA]]` (default: `photo_gray.png` from
//! `../shared/bench-data`, σ = 8). Writes `watershed_labels.png` into the system temp directory.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::core::Plane;
use quarry::vision::io::load_gray;
use quarry::vision::render::render_labels;
use quarry::vision::{RampBlurWatershed, RegionAdjacency, RegionMapping, region_stats};
use std::path::PathBuf;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().map_or_else(
        || {
            std::env::var_os("QUARRY_SHARED")
                .map_or_else(
                    || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
                    PathBuf::from,
                )
                .join("bench-data/photo_gray.png")
        },
        PathBuf::from,
    );
    let sigma: f64 = args
        .get(1)
        .map_or(8.0, |s| s.parse().expect("SIGMA must be a number"));
    let frame = if path.exists() {
        load_gray(&path).unwrap()
    } else {
        eprintln!("{} not found: using a synthetic frame", path.display());
        Plane::from_fn(320, 240, |x, y| {
            let d = |cx: f64, cy: f64| {
                ((f64::from(x) - cx).powi(2) + (f64::from(y) - cy).powi(2)).sqrt()
            };
            if d(100.0, 120.0) < 30.0 || d(220.0, 100.0) < 25.0 {
                40
            } else {
                200
            }
        })
    };

    let segmenter = RampBlurWatershed::new(sigma);
    let t = Instant::now();
    let out = segmenter.run(&frame).unwrap();
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let seg = &out.segmentation;
    println!(
        "{}x{}: {} regions in {ms:.1} ms (sigma {sigma})",
        frame.width,
        frame.height,
        seg.n_regions()
    );

    let adj = RegionAdjacency::from_segmentation(seg).unwrap();
    let stats = region_stats(seg, &frame).unwrap();
    for s in stats.iter().take(5) {
        let m = &seg.minima[s.label as usize - 1];
        println!(
            "region {:3}: {:6} px, mean grey {:6.1}, minimum at {:?}, {} neighbours",
            s.label,
            s.area,
            s.mean,
            m.representative,
            adj.of(s.label).len()
        );
    }

    // A second frame: the same image shifted right by 2 px (a static camera sees motion as a
    // shift of the content); map the regions of frame 0 onto frame 1.
    let shifted = Plane::from_fn(frame.width, frame.height, |x, y| {
        *frame.get(x.saturating_sub(2), y).unwrap()
    });
    let next = segmenter.run(&shifted).unwrap().segmentation;
    let map = RegionMapping::new(seg, &next).unwrap();
    println!(
        "mapping onto the shifted frame: {} bidirectional, {} merges, {} splits",
        map.bidirectional.len(),
        map.merges.len(),
        map.splits.len()
    );

    let png = std::env::temp_dir().join("watershed_labels.png");
    render_labels(seg).unwrap().save(&png).unwrap();
    println!("label image with seeds: {}", png.display());
}
