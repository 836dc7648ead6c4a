//! SLAMOT benchmarks (spec 000 §6.3), single-threaded (a one-thread rayon pool) unless stated:
//!
//! - `slamot_b1/epoch/N`: one observation epoch of S0 (8 control predictions + landmark and
//!   target update + resampling) at t ≈ 40 s, N particles (B1).
//! - `slamot_b2/{persistent,vec}/M`: N = 100 particles whose maps start as one shared prior map
//!   of M landmarks (`SlamotTracker::with_prior_map`); one epoch observes 10 random known
//!   landmarks (no targets) and resamples when N_eff < 0.75 N (B2: the O(N log M) claim; the
//!   tree store should grow ~log M, the Vec store ~M).
//! - `slamot_goal/n1000_m1000`: 1000 particles, 1000 landmarks in the map, 13 landmark and 3
//!   target detections per epoch, one core (the 10 Hz goal = 100 ms per epoch).
//! - `slamot_ekf/epoch/dD`: the EKF-SLAMOT baseline on B1's epoch (state dimension D).
//! - `slamot_b4/threads/T`: B1 at N = 600 with T rayon threads.
//! - `slamot_smoother/mrclam6_robotK/{plain,calibrated}`: the batch smoother over the whole of
//!   MRCLAM dataset 6 for robot K = 1, 3 (started from one N = 20 filter run made once outside
//!   the timing; skipped with a printed reason when `shared/data/mrclam-6` is absent).
//!
//! `cargo bench --bench slamot -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::{Matrix2, Vector2};
use quarry::core::{Gaussian, LandmarkId, LandmarkStore, MultiTargetTracker, Pose2, Stamp};
use quarry::repro::slamot::observation;
use quarry::sim::slamot::{SlamotScenarioConfig, simulate};
use quarry::trackers::ekf_slamot::EkfSlamot;
use quarry::trackers::slamot::{
    DefaultStore, FlatStore, SlamotConfig, SlamotObservation, SlamotTracker,
};
use rand::Rng;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// S0 tracker advanced to t = 40 s, plus the frames of the next epoch.
fn s0_at_40s(n: usize) -> (SlamotTracker<DefaultStore>, Vec<(Stamp, SlamotObservation)>) {
    let scen = SlamotScenarioConfig::s0();
    let frames = simulate(&scen, 3).unwrap();
    let cfg = SlamotConfig {
        particles: n,
        ..SlamotConfig::default()
    };
    let mut tr = SlamotTracker::new(cfg, Pose2::new(4.0, 54.0, 0.0), 7).unwrap();
    let k40 = (40.0 / scen.dt_control) as usize;
    for f in &frames[..k40] {
        tr.step(Stamp::from_frame(f.k, scen.dt_control), &observation(f))
            .unwrap();
    }
    let next: Vec<_> = frames[k40..k40 + scen.obs_every as usize]
        .iter()
        .map(|f| (Stamp::from_frame(f.k, scen.dt_control), observation(f)))
        .collect();
    (tr, next)
}

fn b1(c: &mut Criterion) {
    let one = pool(1);
    let mut g = c.benchmark_group("slamot_b1");
    g.sample_size(10);
    for n in [20usize, 50, 100, 200, 400, 1000] {
        let (tr, next) = s0_at_40s(n);
        g.bench_with_input(BenchmarkId::new("epoch", n), &n, |b, _| {
            b.iter_batched(
                || tr.clone(),
                |mut t| {
                    one.install(|| {
                        for (s, o) in &next {
                            black_box(t.step(*s, o).unwrap());
                        }
                    });
                    t
                },
                criterion::BatchSize::LargeInput,
            );
        });
    }
    g.finish();
}

/// The EKF-SLAMOT baseline on the same S0 epoch at t = 40 s as B1 (one thread; the EKF does
/// not use rayon).
fn ekf(c: &mut Criterion) {
    let scen = SlamotScenarioConfig::s0();
    let frames = simulate(&scen, 3).unwrap();
    let mut e = EkfSlamot::new(SlamotConfig::default(), Pose2::new(4.0, 54.0, 0.0)).unwrap();
    let k40 = (40.0 / scen.dt_control) as usize;
    for f in &frames[..k40] {
        e.step(Stamp::from_frame(f.k, scen.dt_control), &observation(f))
            .unwrap();
    }
    let next: Vec<_> = frames[k40..k40 + scen.obs_every as usize]
        .iter()
        .map(|f| (Stamp::from_frame(f.k, scen.dt_control), observation(f)))
        .collect();
    let mut g = c.benchmark_group("slamot_ekf");
    g.sample_size(20);
    g.bench_function(format!("epoch/d{}", e.dim()), |b| {
        b.iter_batched(
            || e.clone(),
            |mut t| {
                for (s, o) in &next {
                    black_box(t.step(*s, o).unwrap());
                }
                t
            },
            criterion::BatchSize::LargeInput,
        );
    });
    g.finish();
}

fn b4(c: &mut Criterion) {
    let mut g = c.benchmark_group("slamot_b4");
    g.sample_size(10);
    let (tr, next) = s0_at_40s(600);
    for threads in [1usize, 2] {
        let p = pool(threads);
        g.bench_with_input(BenchmarkId::new("threads", threads), &threads, |b, _| {
            b.iter_batched(
                || tr.clone(),
                |mut t| {
                    p.install(|| {
                        for (s, o) in &next {
                            black_box(t.step(*s, o).unwrap());
                        }
                    });
                    t
                },
                criterion::BatchSize::LargeInput,
            );
        });
    }
    g.finish();
}

/// A tracker whose maps hold `m` landmarks at known positions around the robot, plus a set of
/// observation epochs with `k_obs` random known landmarks each (and `targets` target detections).
fn synthetic<S>(
    n: usize,
    m: usize,
    k_obs: usize,
    with_targets: bool,
) -> (SlamotTracker<S>, Vec<SlamotObservation>)
where
    S: LandmarkStore<Gaussian<2>> + FromIterator<Gaussian<2>> + Send + Sync,
{
    let cfg = SlamotConfig {
        particles: n,
        ..SlamotConfig::default()
    };
    let mut rng = quarry::core::rng::seeded(5);
    let lm: Vec<[f64; 2]> = (0..m)
        .map(|_| {
            let r = rng.random_range(2.0..30.0);
            let b = rng.random_range(-3.1..3.1);
            [r, b]
        })
        .collect();
    // spec B2: every particle's map pre-filled with the same M landmarks (shared)
    let prior: Vec<(LandmarkId, Gaussian<2>)> = lm
        .iter()
        .enumerate()
        .map(|(i, z)| {
            let mean = Vector2::new(z[0] * z[1].cos(), z[0] * z[1].sin());
            (
                LandmarkId(i as u32),
                Gaussian::try_new(mean, Matrix2::identity() * 0.0025).unwrap(),
            )
        })
        .collect();
    let mut tr = SlamotTracker::<S>::with_prior_map(cfg, Pose2::identity(), 1, &prior).unwrap();
    let targets = vec![[10.0, 0.5], [12.0, -0.4], [15.0, 2.0]];
    if with_targets {
        let init = SlamotObservation {
            dt: 0.0,
            odometry: (0.0, 0.0),
            observe: true,
            landmark_obs: vec![],
            target_obs: targets.clone(),
        };
        tr.step(Stamp::from_frame(0, 0.2), &init).unwrap();
    }
    let epochs: Vec<SlamotObservation> = (0..16)
        .map(|_| SlamotObservation {
            dt: 0.2,
            odometry: (0.0, 0.0),
            observe: true,
            landmark_obs: (0..k_obs)
                .map(|_| {
                    let i = rng.random_range(0..m);
                    let z = lm[i];
                    (
                        LandmarkId(i as u32),
                        [
                            z[0] + 0.1 * rng.random::<f64>(),
                            z[1] + 0.01 * rng.random::<f64>(),
                        ],
                    )
                })
                .collect(),
            target_obs: if with_targets {
                targets.clone()
            } else {
                vec![]
            },
        })
        .collect();
    // Warm up to the steady state of per-particle copied paths.
    for (k, o) in epochs.iter().cycle().take(48).enumerate() {
        tr.step(Stamp::from_frame(k as u64 + 1, 0.2), o).unwrap();
    }
    (tr, epochs)
}

fn b2(c: &mut Criterion) {
    let one = pool(1);
    let mut g = c.benchmark_group("slamot_b2");
    g.sample_size(10);
    for m in [100usize, 1_000, 10_000, 100_000] {
        let (tp, ep) = synthetic::<DefaultStore>(100, m, 10, false);
        g.bench_with_input(BenchmarkId::new("persistent", m), &m, |b, _| {
            let mut t = tp.clone();
            let mut k = 100u64;
            b.iter(|| {
                one.install(|| {
                    let o = &ep[(k % 16) as usize];
                    black_box(t.step(Stamp::from_frame(k, 0.2), o).unwrap());
                });
                k += 1;
            });
        });
        drop(tp);
        let (tv, ev) = synthetic::<FlatStore>(100, m, 10, false);
        g.bench_with_input(BenchmarkId::new("vec", m), &m, |b, _| {
            let mut t = tv.clone();
            let mut k = 100u64;
            b.iter(|| {
                one.install(|| {
                    let o = &ev[(k % 16) as usize];
                    black_box(t.step(Stamp::from_frame(k, 0.2), o).unwrap());
                });
                k += 1;
            });
        });
    }
    g.finish();
}

fn goal(c: &mut Criterion) {
    let one = pool(1);
    let mut g = c.benchmark_group("slamot_goal");
    g.sample_size(10);
    let (tp, ep) = synthetic::<DefaultStore>(1000, 1000, 13, true);
    g.bench_function("n1000_m1000", |b| {
        let mut t = tp.clone();
        let mut k = 100u64;
        b.iter(|| {
            one.install(|| {
                let o = &ep[(k % 16) as usize];
                black_box(t.step(Stamp::from_frame(k, 0.2), o).unwrap());
            });
            k += 1;
        });
    });
    g.finish();
}

fn smoother(c: &mut Criterion) {
    let dir = std::env::var_os("QUARRY_SHARED")
        .map_or_else(
            || std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
            std::path::PathBuf::from,
        )
        .join("data/mrclam-6");
    if !dir.join("Barcodes.dat").exists() {
        eprintln!(
            "skipping slamot_smoother: no MRCLAM data at {}",
            dir.display()
        );
        return;
    }
    let mut g = c.benchmark_group("slamot_smoother");
    g.sample_size(10);
    for robot in [1, 3] {
        let run = quarry::data::mrclam::load(&dir, robot).unwrap();
        let cfg = quarry::repro::slamot::mrclam_config(20);
        let fwd = quarry::repro::slamot::run_mrclam(&cfg, &run, 1).unwrap();
        for (name, calibrate) in [("plain", false), ("calibrated", true)] {
            g.bench_function(format!("mrclam6_robot{robot}/{name}"), |b| {
                b.iter(|| {
                    black_box(
                        quarry::repro::slamot::smooth_mrclam(&cfg, &run, &fwd, calibrate).unwrap(),
                    )
                });
            });
        }
    }
    g.finish();
}

criterion_group!(benches, b1, b2, goal, ekf, b4, smoother);
criterion_main!(benches);
