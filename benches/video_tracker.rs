//! The full watershed + SIFT tracker (spec 004) per frame, one thread, both profiles:
//!
//! - at 768×576 on PETS09-S2L1: the tracker is run over frames 1-20, then each sample steps a
//!   clone of that state on frame 21 (the clone is not timed). Skipped with a message when the
//!   data are absent (`../shared/data/pets09-s2l1`).
//! - at 800×450 on the synthetic `walkers-v1-ab` and `walkers-v1` (spec §7.2), generated in
//!   process (no data needed): the tracker is run over frames 0-249, then each sample steps a
//!   clone on frame 250 (A and B live in both; C and D too in `walkers-v1`).
//!
//! `cargo bench --bench video_tracker -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use quarry::core::{MultiTargetTracker, Stamp};
use quarry::trackers::watershed_sift::{WatershedSiftConfig, WatershedSiftTracker};
use quarry::vision::convert::rgb_to_gray_bt601;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

fn frames() -> Option<Vec<quarry::core::Plane<u8>>> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    let dir = p.join("data/pets09-s2l1/img1");
    let Ok(files) = quarry::data::image_sequence::list_frames(&dir) else {
        eprintln!(
            "skipping video_tracker benches: no frames in {}",
            dir.display()
        );
        return None;
    };
    Some(
        files
            .iter()
            .take(21)
            .map(|f| rgb_to_gray_bt601(&quarry::vision::io::open_image(f).unwrap().to_rgb8()))
            .collect(),
    )
}

/// A rayon pool of one thread (the benches are single-threaded).
fn one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
}

fn walkers(c: &mut Criterion) {
    use quarry::sim::walkers::{WalkersScenario, WalkersVariant};
    const AT: u64 = 250;
    let one = one_thread();
    let mut g = c.benchmark_group("video_tracker");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    for variant in [WalkersVariant::Ab, WalkersVariant::V1] {
        let sc = WalkersScenario::new(variant).unwrap();
        let last = sc.frame(AT).unwrap();
        for (name, cfg) in [
            ("paper", WatershedSiftConfig::paper()),
            ("robust", WatershedSiftConfig::robust()),
        ] {
            let mut warm = WatershedSiftTracker::new(cfg).unwrap();
            one.install(|| {
                for t in 0..AT {
                    warm.step(Stamp::from_frame(t, 0.04), &sc.frame(t).unwrap())
                        .unwrap();
                }
            });
            g.bench_function(
                format!("{}_800x450_frame{AT}/{name}", variant.name()),
                |b| {
                    b.iter_batched(
                        || warm.clone(),
                        |mut t| {
                            one.install(|| {
                                black_box(t.step(Stamp::from_frame(AT, 0.04), &last).unwrap())
                            })
                        },
                        BatchSize::LargeInput,
                    );
                },
            );
        }
    }
    g.finish();
}

fn video_tracker(c: &mut Criterion) {
    let Some(frames) = frames() else { return };
    let one = one_thread();
    let mut g = c.benchmark_group("video_tracker");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    for (name, cfg) in [
        ("paper", WatershedSiftConfig::paper()),
        ("robust", WatershedSiftConfig::robust()),
    ] {
        let cfg = cfg.with_person_size(32.0, 84.0);
        let mut warm = WatershedSiftTracker::new(cfg).unwrap();
        one.install(|| {
            for (k, f) in frames[..20].iter().enumerate() {
                warm.step(Stamp::from_frame(k as u64, 1.0 / 7.0), f)
                    .unwrap();
            }
        });
        let last = &frames[20];
        g.bench_function(format!("pets09_768x576_frame21/{name}"), |b| {
            b.iter_batched(
                || warm.clone(),
                |mut t| {
                    one.install(|| {
                        black_box(t.step(Stamp::from_frame(20, 1.0 / 7.0), last).unwrap())
                    })
                },
                BatchSize::LargeInput,
            );
        });
    }
    g.finish();
}

criterion_group!(benches, video_tracker, walkers);
criterion_main!(benches);
