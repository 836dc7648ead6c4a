//! The full watershed + SIFT tracker (spec 004) per frame, one thread, both profiles:
//!
//! - at 768×576 on PETS09-S2L1: the tracker is run over frames 1-20, then each sample steps a
//!   clone of that state on frame 21 (the clone is not timed). Skipped with a message when the
//!   data are absent (`../shared/data/pets09-s2l1`).
//! - at 800×450 on the synthetic `walkers-v1-ab` and `walkers-v1` (spec §7.2), generated in
//!   process (no data needed): the tracker is run over frames 0-249, then each sample steps a
//!   clone on frame 250 (A and B live in both; C and D too in `walkers-v1`).
//!
//! - per stage (`video_tracker_stages/...`), one thread, on PETS frame 21 and `walkers-v1`
//!   frame 250, both profiles: the tracker is run up to the frame before (state A) and through
//!   the frame (state B), then each stage is timed on its own —
//!   `segment` (ramp, blur, minima, watershed: `MotionFrontEnd::segment` of state A's front
//!   end), `map` (region mapping from the previous frame, trajectory update and region
//!   adjacency), `moving` (the moving-point test on state B's trajectories), `sift` (step 8's
//!   SIFT on every live target's ROI crop, state B, empty crop cache) and `pools` (step 8's pool
//!   updates with those features, on a clone of state B). Segmentation, mapping and moving
//!   points do not depend on the profile (same σ and test), so they are timed once per video.
//!   The SIFT calls of steps 4 and 6 (fragments, moving points) and the foreground stage of
//!   `robust` are not split out; the full-frame rows hold them.
//!
//! `cargo bench --bench video_tracker -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use quarry::core::Plane;
use quarry::core::{MultiTargetTracker, Stamp};
use quarry::trackers::watershed_sift::{WatershedSiftConfig, WatershedSiftTracker};
use quarry::vision::convert::rgb_to_gray_bt601;
use quarry::vision::{RegionAdjacency, RegionMapping};
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

/// Feeds the frames before the timed one, `(index, frame)`, to a callback.
type Frames<'a> = dyn Fn(&mut dyn FnMut(u64, &Plane<u8>)) + Sync + 'a;

/// The per-stage cases of one frame `last` (index `at`) after `before` (the frames up to it),
/// for both profiles built by `cfg`.
fn stage_cases(
    c: &mut Criterion,
    name: &str,
    before: &Frames<'_>,
    at: u64,
    dt: f64,
    last: &Plane<u8>,
    cfg: &dyn Fn(WatershedSiftConfig) -> WatershedSiftConfig,
) {
    let one = one_thread();
    let mut g = c.benchmark_group("video_tracker_stages");
    g.sample_size(20).measurement_time(Duration::from_secs(5));
    for (profile, base) in [
        ("paper", WatershedSiftConfig::paper()),
        ("robust", WatershedSiftConfig::robust()),
    ] {
        let mut a = WatershedSiftTracker::new(cfg(base)).unwrap();
        one.install(|| {
            before(&mut |t, f| {
                a.step(Stamp::from_frame(t, dt), f).unwrap();
            });
        });
        let mut b = a.clone();
        one.install(|| b.step(Stamp::from_frame(at, dt), last).unwrap());
        if profile == "paper" {
            let front = a.front_end();
            g.bench_function(format!("{name}/segment"), |bn| {
                bn.iter(|| one.install(|| black_box(front.segment(last).unwrap())));
            });
            let prev = front.current().unwrap();
            let seg = b.front_end().current().unwrap();
            let traj = front.trajectories().unwrap();
            g.bench_function(format!("{name}/map"), |bn| {
                bn.iter_batched(
                    || traj.clone(),
                    |mut tr| {
                        one.install(|| {
                            let map = RegionMapping::new(prev, seg).unwrap();
                            tr.advance(&map, seg).unwrap();
                            black_box((map, RegionAdjacency::from_segmentation(seg).unwrap()))
                        })
                    },
                    BatchSize::LargeInput,
                );
            });
            let (tr, test) = (b.front_end().trajectories().unwrap(), b.front_end().test());
            g.bench_function(format!("{name}/moving"), |bn| {
                bn.iter(|| black_box(tr.moving_points(test).unwrap()));
            });
        }
        let feats = one.install(|| b.stage_roi_features(last).unwrap());
        let crops = feats.iter().flatten().count();
        let keypoints: usize = feats.iter().flatten().map(|f| f.1.len()).sum();
        eprintln!(
            "{name}/{profile}: {} targets, {crops} ROI crops, {keypoints} descriptors",
            b.targets().len()
        );
        g.bench_function(format!("{name}/sift/{profile}"), |bn| {
            bn.iter(|| one.install(|| black_box(b.stage_roi_features(last).unwrap())));
        });
        g.bench_function(format!("{name}/pools/{profile}"), |bn| {
            bn.iter_batched(
                || (b.clone(), feats.clone()),
                |(mut tr, f)| black_box(tr.stage_pool_updates(at, f).unwrap()),
                BatchSize::LargeInput,
            );
        });
    }
    g.finish();
}

fn stages(c: &mut Criterion) {
    if let Some(frames) = frames() {
        stage_cases(
            c,
            "pets09_768x576_frame21",
            &|f| {
                for (k, p) in frames[..20].iter().enumerate() {
                    f(k as u64, p);
                }
            },
            20,
            1.0 / 7.0,
            &frames[20],
            &|cfg| cfg.with_person_size(32.0, 84.0),
        );
    }
    use quarry::sim::walkers::{WalkersScenario, WalkersVariant};
    const AT: u64 = 250;
    let sc = WalkersScenario::new(WalkersVariant::V1).unwrap();
    stage_cases(
        c,
        "walkers-v1_800x450_frame250",
        &|f| {
            for t in 0..AT {
                f(t, &sc.frame(t).unwrap());
            }
        },
        AT,
        0.04,
        &sc.frame(AT).unwrap(),
        &|cfg| cfg,
    );
}

criterion_group!(benches, video_tracker, walkers, stages);
criterion_main!(benches);
