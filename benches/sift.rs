//! SIFT benchmarks on `../shared/bench-data/photo_gray.png` (800×450): detect + describe with one
//! and with two rayon threads, and descriptor matching (brute force and k-d tree) of photo_gray
//! against `sift_rot30_s0.8.png`. Compare with `peers/bench_sift.py` (OpenCV, same inputs).
//!
//! `cargo bench --bench sift -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use quarry::vision::matching::{BruteForceL2, DescriptorMatcher, KdTreeMatcher};
use quarry::vision::sift::Sift;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

fn bench_data() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    let p = p.join("bench-data");
    if p.join("photo_gray.png").exists() {
        Some(p)
    } else {
        eprintln!("skipping SIFT benches: no bench-data at {}", p.display());
        None
    }
}

fn sift(c: &mut Criterion) {
    let Some(dir) = bench_data() else { return };
    let img = quarry::vision::io::load_gray(dir.join("photo_gray.png")).unwrap();
    let img2 = quarry::vision::io::load_gray(dir.join("sift_rot30_s0.8.png")).unwrap();
    let sift = Sift::default();
    let mut g = c.benchmark_group("sift");
    g.sample_size(15).measurement_time(Duration::from_secs(6));
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        g.bench_function(
            format!("detect_and_compute photo_gray 800x450 {threads} thread(s)"),
            |b| {
                pool.install(|| b.iter(|| black_box(sift.extract(black_box(&img)).unwrap())));
            },
        );
    }
    let (_, d1) = sift.extract(&img).unwrap();
    let (_, d2) = sift.extract(&img2).unwrap();
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        g.bench_function(
            format!(
                "BruteForceL2 nearest2 {}x{} {threads} thread(s)",
                d1.len(),
                d2.len()
            ),
            |b| pool.install(|| b.iter(|| black_box(BruteForceL2.nearest2(&d1, &d2)))),
        );
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let kd = KdTreeMatcher::default();
    g.bench_function(
        format!(
            "KdTreeMatcher(256 checks) nearest2 {}x{} 1 thread",
            d1.len(),
            d2.len()
        ),
        |b| pool.install(|| b.iter(|| black_box(kd.nearest2(&d1, &d2)))),
    );
    g.finish();
}

criterion_group!(benches, sift);
criterion_main!(benches);
