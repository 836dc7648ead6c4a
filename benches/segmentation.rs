//! Segmentation benchmarks on `../shared/bench-data/photo_gray.png` (800×450), mirroring
//! `peers/bench_blur.py` and `peers/bench_watershed.py`:
//!
//! * blur: f32 image, σ = 8 (65 taps, reflect-101), 1 and 2 threads (cv2.GaussianBlur);
//! * regional minima on the σ-8 blurred f32 image, 4-connected like `skimage.morphology.local_minima(
//!   connectivity=1)`, and 8-connected (spec 004);
//! * watershed of the same image from those seeds, 4-connected like
//!   `skimage.segmentation.watershed` (and 8-connected);
//! * the whole segmentation step of spec 004 (ramp + f64 blur σ = 8 + minima + watershed,
//!   8-connected) on one thread, and its stages (minima + flood as separate calls, and
//!   `watershed()`, which takes the minima from the flood's own pass).
//!
//! A second group, `segmentation-cpu`, measures the same single-thread workloads in *CPU time of
//! the running thread* (`/proc/thread-self/schedstat`, Linux; the group is skipped elsewhere)
//! instead of wall time, so that the figures stay meaningful while other processes load the
//! machine (criterion still prints them as "time").
//!
//! `cargo bench --bench segmentation -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use criterion::{Criterion, SamplingMode, criterion_group, criterion_main};
use quarry::vision::{
    Connectivity, RampBlurWatershed, WatershedOptions, add_regular_ramp, flood, gaussian_blur_f32,
    gaussian_blur_f64, regional_minima, watershed,
};
use std::fs;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

fn photo() -> Option<quarry::core::Plane<u8>> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    let p = p.join("bench-data/photo_gray.png");
    if p.exists() {
        Some(quarry::vision::io::load_gray(p).unwrap())
    } else {
        eprintln!("skipping segmentation benches: no {}", p.display());
        None
    }
}

fn segmentation(c: &mut Criterion) {
    let Some(img) = photo() else { return };
    let img32 = img.map(|&v| f32::from(v));
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let blurred = gaussian_blur_f32(&img32, 8.0).unwrap();
    let mut g = c.benchmark_group("segmentation");
    g.sample_size(30).measurement_time(Duration::from_secs(4));

    for (threads, pool) in [(1, &one), (2, &two)] {
        g.bench_function(
            format!("blur f32 sigma8 800x450 {threads} thread(s)"),
            |b| {
                b.iter(|| {
                    pool.install(|| black_box(gaussian_blur_f32(black_box(&img32), 8.0).unwrap()))
                });
            },
        );
    }
    for (name, conn) in [
        ("4-conn", Connectivity::Four),
        ("8-conn", Connectivity::Eight),
    ] {
        g.bench_function(format!("regional minima {name} blurred f32"), |b| {
            b.iter(|| black_box(regional_minima(black_box(&blurred), conn).unwrap()));
        });
        let seeds = regional_minima(&blurred, conn).unwrap();
        let opts = WatershedOptions { connectivity: conn };
        g.bench_function(format!("watershed {name} blurred f32"), |b| {
            b.iter(|| black_box(flood(black_box(&blurred), &seeds, opts).unwrap()));
        });
    }

    // the spec-004 step on one thread, and its stages
    let seg = RampBlurWatershed::default();
    g.bench_function("ramp f64", |b| {
        b.iter(|| black_box(add_regular_ramp(black_box(&img), 256).unwrap()));
    });
    let ramped = add_regular_ramp(&img, 256).unwrap();
    g.bench_function("blur f64 sigma8 1 thread", |b| {
        b.iter(|| one.install(|| black_box(gaussian_blur_f64(black_box(&ramped), 8.0).unwrap())));
    });
    let relief = gaussian_blur_f64(&ramped, 8.0).unwrap();
    g.bench_function("minima + watershed 8-conn f64 relief", |b| {
        b.iter(|| {
            let s = regional_minima(black_box(&relief), Connectivity::Eight).unwrap();
            black_box(flood(&relief, &s, WatershedOptions::default()).unwrap())
        });
    });
    g.bench_function("watershed() 8-conn f64 relief (minima fused)", |b| {
        b.iter(|| black_box(watershed(black_box(&relief), WatershedOptions::default()).unwrap()));
    });
    g.bench_function("relief (ramp fused into f64 blur) 1 thread", |b| {
        b.iter(|| one.install(|| black_box(seg.relief(black_box(&img)).unwrap())));
    });
    g.bench_function(
        "whole step (ramp + blur + minima + watershed) 1 thread",
        |b| {
            b.iter(|| one.install(|| black_box(seg.run(black_box(&img)).unwrap())));
        },
    );
    g.finish();
}

/// CPU time consumed so far by the calling thread (scheduler accounting, nanoseconds).
fn thread_cpu() -> Option<Duration> {
    let s = fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: u64 = s.split_whitespace().next()?.parse().ok()?;
    Some(Duration::from_nanos(ns))
}

/// The single-thread workloads timed in CPU time of the (one) rayon worker that runs them.
fn segmentation_cpu(c: &mut Criterion) {
    let Some(img) = photo() else { return };
    if thread_cpu().is_none() {
        eprintln!("skipping segmentation-cpu: no /proc/thread-self/schedstat");
        return;
    }
    let img32 = img.map(|&v| f32::from(v));
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let blurred = gaussian_blur_f32(&img32, 8.0).unwrap();
    let seg = RampBlurWatershed::default();
    let relief = seg.relief(&img).unwrap();
    let seeds4 = regional_minima(&blurred, Connectivity::Four).unwrap();
    let mut g = c.benchmark_group("segmentation-cpu");
    // equal iteration counts per sample (~0.1 s each), so the scheduler's accounting granularity
    // is small against every sample
    g.sampling_mode(SamplingMode::Flat)
        .sample_size(20)
        .measurement_time(Duration::from_secs(4));
    let mut cpu = |name: &str, f: &mut (dyn FnMut() + Send)| {
        g.bench_function(name, |b| {
            b.iter_custom(|iters| {
                one.install(|| {
                    let t0 = thread_cpu().unwrap();
                    for _ in 0..iters {
                        f();
                    }
                    thread_cpu().unwrap().saturating_sub(t0)
                })
            });
        });
    };
    cpu("blur f32 sigma8 800x450", &mut || {
        black_box(gaussian_blur_f32(black_box(&img32), 8.0).unwrap());
    });
    cpu("regional minima 4-conn blurred f32", &mut || {
        black_box(regional_minima(black_box(&blurred), Connectivity::Four).unwrap());
    });
    cpu("watershed 4-conn blurred f32", &mut || {
        let opts = WatershedOptions {
            connectivity: Connectivity::Four,
        };
        black_box(flood(black_box(&blurred), &seeds4, opts).unwrap());
    });
    cpu("relief (ramp fused into f64 blur)", &mut || {
        black_box(seg.relief(black_box(&img)).unwrap());
    });
    cpu("minima + watershed 8-conn f64 relief", &mut || {
        let s = regional_minima(black_box(&relief), Connectivity::Eight).unwrap();
        black_box(flood(&relief, &s, WatershedOptions::default()).unwrap());
    });
    cpu("watershed() 8-conn f64 relief (minima fused)", &mut || {
        black_box(watershed(black_box(&relief), WatershedOptions::default()).unwrap());
    });
    cpu("whole step (ramp + blur + minima + watershed)", &mut || {
        black_box(seg.run(black_box(&img)).unwrap());
    });
    g.finish();
}

criterion_group!(benches, segmentation, segmentation_cpu);
criterion_main!(benches);
