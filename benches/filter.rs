//! Filter benchmarks on `../shared/bench-data`, mirroring `../shared/peers/bench_kf.py`,
//! `bench_ekf.py` and `bench_pf.py` exactly (same priors, noise, data; state order converted
//! from the files' [x, vx, y, vy] to quarry's [x, y, vx, vy]):
//!
//! - `kf/cv_pass_1000`: 4-state CV KF (CWNA q = 0.5, dt = 0.1), 2-D position z (σ = 0.5), one
//!   pass over kf_track.csv = 1000 × (predict + Joseph update), filter re-initialised per pass.
//! - `ekf/rb_pass_1000`: CV EKF (q = 0.01) with range-bearing z from the origin
//!   (σ_r = 0.5, σ_b = 0.01), one pass over ekf_rb.csv.
//! - `pf/weight_update/N`, `pf/systematic_resample/N`, `pf/full_step/N` for N = 50, 500, 5000:
//!   CV propagation with process noise, Gaussian position log-likelihood, log-domain
//!   normalisation, weighted mean, systematic resampling every step.
//!
//! - `store_clone_write/{persistent,vec}/M`: copy a particle's map of M landmark Gaussians and
//!   write one landmark (what resampling plus one FastSLAM update costs per particle).
//!
//! `cargo bench --bench filter -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Cholesky, Matrix4, Vector2, Vector4};
use quarry::core::{Gaussian, MotionModel, Pose2, rng::seeded};
use quarry::filter::particles::{Systematic, normalise_log_into};
use quarry::filter::{ConstantVelocity2, Ekf, Position2, RangeBearingCv, UpdateForm};
use rand::Rng;
use rand_distr::StandardNormal;

fn bench_data() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    let d = p.join("bench-data");
    if d.join("kf_track.csv").exists() {
        Some(d)
    } else {
        eprintln!("skipping filter benches: no bench-data at {}", d.display());
        None
    }
}

fn cols(path: &std::path::Path, names: &[&str]) -> Vec<Vector2<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| header.iter().position(|h| h == n).unwrap())
        .collect();
    lines
        .filter(|l| !l.is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            Vector2::new(f[idx[0]].parse().unwrap(), f[idx[1]].parse().unwrap())
        })
        .collect()
}

fn kf_ekf(c: &mut Criterion) {
    let Some(dir) = bench_data() else { return };
    let zs = cols(&dir.join("kf_track.csv"), &["zx", "zy"]);
    let cv = ConstantVelocity2::cwna(0.5).unwrap();
    let pos = Position2::isotropic(0.5).unwrap();
    let x0 = Gaussian::try_new(Vector4::new(0.0, 0.0, 1.0, 0.5), Matrix4::identity()).unwrap();
    let mut g = c.benchmark_group("kf");
    g.throughput(Throughput::Elements(zs.len() as u64));
    for (name, form) in [
        ("cv_pass_1000", UpdateForm::Joseph),
        ("cv_pass_1000_standard", UpdateForm::Standard),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut kf = Ekf::new(x0, cv, pos).unwrap().with_form(form);
                for z in &zs {
                    kf.predict(&(), 0.1).unwrap();
                    kf.update(black_box(z)).unwrap();
                }
                *kf.mean()
            });
        });
    }
    g.finish();

    let zs = cols(&dir.join("ekf_rb.csv"), &["range", "bearing"]);
    let cv = ConstantVelocity2::cwna(0.01).unwrap();
    let rb = RangeBearingCv::new(Pose2::identity(), 0.5, 0.01).unwrap();
    let x0 = Gaussian::try_new(
        Vector4::new(40.0, 10.0, 0.5, 1.0),
        Matrix4::from_diagonal(&Vector4::new(4.0, 4.0, 1.0, 1.0)),
    )
    .unwrap();
    let mut g = c.benchmark_group("ekf");
    g.throughput(Throughput::Elements(zs.len() as u64));
    g.bench_function("rb_pass_1000", |b| {
        b.iter(|| {
            let mut ekf = Ekf::new(x0, cv, rb).unwrap();
            for z in &zs {
                ekf.predict(&(), 0.1).unwrap();
                ekf.update(black_box(z)).unwrap();
            }
            *ekf.mean()
        });
    });
    g.finish();
}

/// The particle filter of bench_pf.py: particles [x, y, vx, vy].
struct Pf {
    x: Vec<Vector4<f64>>,
    scratch: Vec<Vector4<f64>>,
    log_w: Vec<f64>,
    w: Vec<f64>,
    idx: Vec<usize>,
    f: Matrix4<f64>,
    lq: Matrix4<f64>,
    rng: quarry::core::rng::SeededRng,
    k: usize,
}

const SIGMA: f64 = 0.5;

impl Pf {
    fn new(n: usize, seed: u64) -> Self {
        let cv = ConstantVelocity2::cwna(0.5).unwrap();
        let f = cv.jacobian(&Vector4::zeros(), &(), 0.1);
        let q = cv.process_noise(&Vector4::zeros(), &(), 0.1);
        let lq = Cholesky::new(q).unwrap().l();
        let mut rng = seeded(seed);
        let x0 = Vector4::new(0.0, 0.0, 1.0, 0.5);
        let x = (0..n).map(|_| x0 + randn4(&mut rng)).collect();
        Self {
            x,
            scratch: vec![Vector4::zeros(); n],
            log_w: vec![0.0; n],
            w: vec![0.0; n],
            idx: Vec::with_capacity(n),
            f,
            lq,
            rng,
            k: 0,
        }
    }

    fn weight_update(&mut self, z: &Vector2<f64>) {
        let s = -0.5 / (SIGMA * SIGMA);
        for (lw, x) in self.log_w.iter_mut().zip(&self.x) {
            let (dx, dy) = (x[0] - z[0], x[1] - z[1]);
            *lw = s * (dx * dx + dy * dy);
        }
        normalise_log_into(&self.log_w, &mut self.w).unwrap();
    }

    fn step(&mut self, zs: &[Vector2<f64>]) -> Vector2<f64> {
        let z = zs[self.k % zs.len()];
        self.k += 1;
        for x in &mut self.x {
            *x = self.f * *x + self.lq * randn4(&mut self.rng);
        }
        self.weight_update(&z);
        let mut est = Vector2::zeros();
        for (w, x) in self.w.iter().zip(&self.x) {
            est += Vector2::new(x[0], x[1]) * *w;
        }
        Systematic
            .resample_into(&self.w, &mut self.rng, &mut self.idx)
            .unwrap();
        for (s, &i) in self.scratch.iter_mut().zip(&self.idx) {
            *s = self.x[i];
        }
        std::mem::swap(&mut self.x, &mut self.scratch);
        est
    }
}

fn randn4(rng: &mut impl Rng) -> Vector4<f64> {
    Vector4::new(
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
    )
}

fn pf(c: &mut Criterion) {
    let Some(dir) = bench_data() else { return };
    let zs = cols(&dir.join("kf_track.csv"), &["zx", "zy"]);
    let mut g = c.benchmark_group("pf");
    for n in [50usize, 500, 5000] {
        // weight update and resampling on a fixed cloud around the first measurement (the
        // peer's setup: x0 + 0.5 N(0, I)).
        let mut p = Pf::new(n, 1);
        let mut rng = seeded(1);
        let x0 = Vector4::new(0.0, 0.0, 1.0, 0.5);
        for x in &mut p.x {
            *x = x0 + randn4(&mut rng) * 0.5;
        }
        let z = zs[0];
        g.bench_with_input(BenchmarkId::new("weight_update", n), &n, |b, _| {
            b.iter(|| {
                p.weight_update(black_box(&z));
                p.w[0]
            });
        });
        p.weight_update(&z);
        let w = p.w.clone();
        let mut out = Vec::with_capacity(n);
        let mut rng = seeded(2);
        g.bench_with_input(BenchmarkId::new("systematic_resample", n), &n, |b, _| {
            b.iter(|| {
                Systematic
                    .resample_into(black_box(&w), &mut rng, &mut out)
                    .unwrap();
                out[0]
            });
        });
        let mut p = Pf::new(n, 0);
        g.bench_with_input(BenchmarkId::new("full_step", n), &n, |b, _| {
            b.iter(|| p.step(&zs));
        });
    }
    g.finish();
}

/// FastSLAM's map-copy cost: clone a particle's map (resampling) and write one landmark, for
/// M landmark Gaussians, persistent tree vs flat vector.
fn stores(c: &mut Criterion) {
    use quarry::core::{LandmarkId, LandmarkStore};
    use quarry::filter::store::{PersistentStore, VecStore};
    let mut g = c.benchmark_group("store_clone_write");
    for m in [100usize, 1000, 10_000, 100_000] {
        let lm = Gaussian::try_new(Vector2::new(1.0, 2.0), nalgebra::Matrix2::identity()).unwrap();
        let ps: PersistentStore<Gaussian<2>> = std::iter::repeat_n(lm, m).collect();
        let vs: VecStore<Gaussian<2>> = std::iter::repeat_n(lm, m).collect();
        let id = LandmarkId((m / 3) as u32);
        g.bench_with_input(BenchmarkId::new("persistent", m), &m, |b, _| {
            b.iter(|| {
                let mut p = black_box(&ps).clone();
                p.set(id, lm).unwrap();
                p
            });
        });
        g.bench_with_input(BenchmarkId::new("vec", m), &m, |b, _| {
            b.iter(|| {
                let mut v = black_box(&vs).clone();
                v.set(id, lm).unwrap();
                v
            });
        });
    }
    g.finish();
}

criterion_group!(benches, kf_ekf, pf, stores);
criterion_main!(benches);
