//! Association benchmarks (quarry-assoc), mirroring `../shared/peers/bench_jpda.py` ("known n"
//! mode) exactly: one CV track per target started at the truth of scan 0 with
//! P0 = diag(0.25, 0.25, 0.05, 0.05) (quarry order [x, y, vx, vy]), CWNA q = 0.001, dt = 1 s,
//! position measurements σ = 0.5 m, P_D 0.9, P_G 0.99 (χ²₂ gate 9.21), clutter density
//! 10/3600 m⁻²; each scan = predict + gate + likelihoods + JPDA + PDA update
//! (`quarry::trackers::cv_jpda::JpdaTracker`, the stand-alone tracker).
//!
//! - `jpda_scan/known/n{3,10,20}`: the whole 100-scan sequence (divide by 100 for per scan).
//! - `jpda_assoc_only/n{3,10,20}`: `Jpda::associate` alone on the 100 likelihood matrices of
//!   that run (divide by 100).
//! - `cluster_sweep/{exact,lbp}/k`: one scan of k = 2..12 mutually gated targets (likelihoods +
//!   association; the scene of `benches/peers/jpda_sweep.py`, which times Stone Soup on it).
//! - `poisson50/scan`: 50 targets in [0, 100]² with P_D 0.9 and Poisson(10) clutter, one scan
//!   = χ² gating + likelihood matrix + exact JPDA (20 pre-drawn scans; divide by 20).
//!
//! `cargo bench --bench assoc -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::path::{Path, PathBuf};

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::{Matrix4, Vector4};
use quarry::assoc::{Jpda, Method, Solver};
use quarry::core::{
    Associator, Gaussian, LikelihoodMatrix, MultiTargetTracker, Stamp, TimeUs, TrackPrior,
    rng::seeded,
};
use quarry::trackers::cv_jpda::{AssocMode, JpdaTracker, JpdaTrackerConfig};
use rand::Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};

fn bench_data() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    let d = p.join("bench-data");
    if d.join("jpda_n3_meas.csv").exists() {
        Some(d)
    } else {
        eprintln!(
            "skipping jpda bench-data benches: no bench-data at {}",
            d.display()
        );
        None
    }
}

fn rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse::<f64>().unwrap())
                .collect()
        })
        .collect()
}

fn load(dir: &Path, n: usize) -> (Vec<Gaussian<4>>, Vec<Vec<[f64; 2]>>) {
    let tr = rows(&dir.join(format!("jpda_n{n}_truth.csv")));
    let me = rows(&dir.join(format!("jpda_n{n}_meas.csv")));
    let scans = tr.iter().map(|r| r[0] as usize).max().unwrap() + 1;
    let p0 = Matrix4::from_diagonal(&Vector4::new(0.25, 0.25, 0.05, 0.05));
    let mut init = vec![Gaussian::try_new(Vector4::zeros(), p0).unwrap(); n];
    for r in tr.iter().filter(|r| r[0] == 0.0) {
        init[r[1] as usize].mean = Vector4::new(r[2], r[3], r[4], r[5]);
    }
    let mut dets = vec![Vec::new(); scans];
    for r in &me {
        dets[r[0] as usize].push([r[1], r[2]]);
    }
    (init, dets)
}

fn cfg() -> JpdaTrackerConfig {
    JpdaTrackerConfig {
        mode: AssocMode::Jpda,
        ..Default::default()
    }
}

/// Per-scan likelihood matrices of a known-target run (computed with the same gate).
fn matrices(init: &[Gaussian<4>], dets: &[Vec<[f64; 2]>]) -> Vec<LikelihoodMatrix> {
    use quarry::filter::ekf::{self, MeasurementPrediction};
    use quarry::filter::{ConstantVelocity2, Position2};
    // Re-run the tracker to get the right priors, and rebuild each scan's matrix from them.
    let mut trk = JpdaTracker::with_tracks(cfg(), init, TimeUs(0)).unwrap();
    let cv = ConstantVelocity2::cwna(0.001).unwrap();
    let pos = Position2::isotropic(0.5).unwrap();
    let gamma = quarry::assoc::ChiSquareGate::new(0.99)
        .unwrap()
        .threshold(2)
        .unwrap();
    let mut out = Vec::new();
    for (k, z) in dets.iter().enumerate() {
        let dt = if k == 0 { 0.0 } else { 1.0 };
        let preds: Vec<_> = trk
            .tracks()
            .iter()
            .map(|t| {
                MeasurementPrediction::<4, 2>::new(
                    &ekf::predict(&t.est, &cv, &(), dt).unwrap(),
                    &pos,
                )
                .unwrap()
            })
            .collect();
        out.push(
            LikelihoodMatrix::from_fn(preds.len(), z.len(), |i, j| {
                let nu = nalgebra::Vector2::new(z[j][0], z[j][1]) - preds[i].zhat;
                let d2 = preds[i].nis(&nu);
                (d2 <= gamma).then(|| preds[i].log_normaliser() - 0.5 * d2)
            })
            .unwrap(),
        );
        trk.step(Stamp::from_frame(k as u64, 1.0), z).unwrap();
    }
    out
}

fn bench_scenarios(c: &mut Criterion) {
    let Some(dir) = bench_data() else { return };
    let jpda = Jpda::new(0.9, 0.99, 10.0 / 3600.0).unwrap();
    for n in [3usize, 10, 20] {
        let (init, dets) = load(&dir, n);
        c.bench_function(&format!("jpda_scan/known/n{n}"), |b| {
            b.iter_batched(
                || JpdaTracker::with_tracks(cfg(), &init, TimeUs(0)).unwrap(),
                |mut trk| {
                    for (k, z) in dets.iter().enumerate() {
                        black_box(trk.step(Stamp::from_frame(k as u64, 1.0), z).unwrap());
                    }
                },
                criterion::BatchSize::SmallInput,
            );
        });
        let mats = matrices(&init, &dets);
        let pri = vec![TrackPrior::default(); n];
        c.bench_function(&format!("jpda_assoc_only/n{n}"), |b| {
            b.iter(|| {
                for m in &mats {
                    black_box(jpda.associate(m, &pri).unwrap());
                }
            });
        });
    }
}

/// k mutually gated targets, the same scene as `benches/peers/jpda_sweep.py`: track i at
/// (0.2 i, 0) with S = I; detection j < k at (0.2 j + 0.1 sin(1.7 j + k), 0.1 cos j), clutter at
/// (0.06 k, 0.3) and (0.14 k, −0.3). Returns (predicted positions, detections).
fn sweep_scene(k: usize) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let kf = k as f64;
    let tracks = (0..k).map(|i| [0.2 * i as f64, 0.0]).collect();
    let mut z: Vec<[f64; 2]> = (0..k)
        .map(|j| {
            let jf = j as f64;
            [0.2 * jf + 0.1 * (1.7 * jf + kf).sin(), 0.1 * jf.cos()]
        })
        .collect();
    z.push([0.06 * kf, 0.3]);
    z.push([0.14 * kf, -0.3]);
    (tracks, z)
}

/// Gaussian log-likelihoods with S = I and the χ²₂(0.99) gate.
fn unit_lik(t: &[[f64; 2]], z: &[[f64; 2]]) -> LikelihoodMatrix {
    let ln2pi = (2.0 * std::f64::consts::PI).ln();
    LikelihoodMatrix::from_fn(t.len(), z.len(), |i, j| {
        let d2 = (z[j][0] - t[i][0]).powi(2) + (z[j][1] - t[i][1]).powi(2);
        (d2 <= 9.2103).then_some(-ln2pi - 0.5 * d2)
    })
    .unwrap()
}

fn bench_sweep(c: &mut Criterion) {
    let mut g = c.benchmark_group("cluster_sweep");
    for k in 2..=12usize {
        let (t, z) = sweep_scene(k);
        assert!(
            unit_lik(&t, &z).matrix().iter().all(|v| v.is_finite()),
            "not mutually gated"
        );
        let pri = vec![TrackPrior::default(); k];
        let exact = Jpda::new(0.9, 0.99, 0.01).unwrap().with_solver(Solver {
            method: Method::Exact,
            ..Solver::default()
        });
        let lbp = Jpda::new(0.9, 0.99, 0.01).unwrap().with_solver(Solver {
            method: Method::Lbp,
            ..Solver::default()
        });
        // Likelihoods + association, as Stone Soup's associate() includes its hypothesiser.
        g.bench_with_input(BenchmarkId::new("exact", k), &k, |b, _| {
            b.iter(|| black_box(exact.associate(&unit_lik(&t, &z), &pri).unwrap()));
        });
        g.bench_with_input(BenchmarkId::new("lbp", k), &k, |b, _| {
            b.iter(|| black_box(lbp.associate(&unit_lik(&t, &z), &pri).unwrap()));
        });
    }
    g.finish();
}

fn bench_poisson50(c: &mut Criterion) {
    // 50 targets with predicted measurement N(ẑ_i, S), S = diag(1, 1) (σ_meas 0.5 plus track
    // uncertainty), detections with P_D 0.9 and N(0, 0.5²) noise, Poisson(10) clutter.
    let mut rng = seeded(50);
    let pois = Poisson::new(10.0).unwrap();
    let gamma = 9.2103;
    let ln_norm = -(2.0 * std::f64::consts::PI).ln();
    type Scene = (Vec<[f64; 2]>, Vec<[f64; 2]>);
    let scans: Vec<Scene> = (0..20)
        .map(|_| {
            let targets: Vec<[f64; 2]> = (0..50)
                .map(|_| [100.0 * rng.random::<f64>(), 100.0 * rng.random::<f64>()])
                .collect();
            let mut z = Vec::new();
            for t in &targets {
                if rng.random::<f64>() < 0.9 {
                    z.push([
                        t[0] + 0.5 * rng.sample::<f64, _>(StandardNormal),
                        t[1] + 0.5 * rng.sample::<f64, _>(StandardNormal),
                    ]);
                }
            }
            let nc: f64 = pois.sample(&mut rng);
            for _ in 0..nc as usize {
                z.push([100.0 * rng.random::<f64>(), 100.0 * rng.random::<f64>()]);
            }
            (targets, z)
        })
        .collect();
    let jpda = Jpda::new(0.9, 0.99, 10.0 / 10_000.0).unwrap();
    let pri = vec![TrackPrior::default(); 50];
    c.bench_function("poisson50/20_scans", |b| {
        b.iter(|| {
            for (t, z) in &scans {
                let lik = LikelihoodMatrix::from_fn(t.len(), z.len(), |i, j| {
                    let dx = z[j][0] - t[i][0];
                    let dy = z[j][1] - t[i][1];
                    let d2 = dx * dx + dy * dy;
                    (d2 <= gamma).then_some(ln_norm - 0.5 * d2)
                })
                .unwrap();
                black_box(jpda.associate(&lik, &pri).unwrap());
            }
        });
    });
}

criterion_group!(benches, bench_scenarios, bench_sweep, bench_poisson50);
criterion_main!(benches);
