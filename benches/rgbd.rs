//! RGB-D person tracker benchmarks (spec 001 §6.3): the patch descriptor of one candidate on
//! `../shared/bench-data/rgbd_rgb.png` + `rgbd_depth.png` (compare with
//! `peers/bench_patch.py`, OpenCV calcHist + scikit-image LBP on the same box), the per-frame
//! feature maps, and one tracker step at 640×480 with K = 54 candidates on a synthetic S1 frame.
//!
//! `cargo bench --bench rgbd -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use quarry::core::{BBox, EgoMotion, Plane, SingleTargetTracker, Stamp};
use quarry::sim::rgbd::{RgbdScene, ScenarioId};
use quarry::trackers::rgbd_person::{RgbdPersonConfig, RgbdPersonTracker};
use quarry::vision::multicue::{PatchModelConfig, PatchMultiCueModel, RgbdFeatures, RgbdFrame};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

fn bench_data() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    let p = p.join("bench-data");
    if p.join("rgbd_rgb.png").exists() {
        Some(p)
    } else {
        eprintln!(
            "skipping rgbd descriptor benches: no bench-data at {}",
            p.display()
        );
        None
    }
}

fn descriptor(c: &mut Criterion) {
    let Some(dir) = bench_data() else { return };
    let rgb = image::open(dir.join("rgbd_rgb.png")).unwrap().to_rgb8();
    let (w, h) = rgb.dimensions();
    let d16 = image::open(dir.join("rgbd_depth.png")).unwrap().to_luma16();
    let depth = Plane::from_vec(
        w,
        h,
        d16.into_raw()
            .into_iter()
            .map(|v| f32::from(v) / 1000.0)
            .collect(),
    )
    .unwrap();
    let raw = rgb.into_raw();
    let cfg = PatchModelConfig::default();
    let mut g = c.benchmark_group("rgbd");
    g.sample_size(30).measurement_time(Duration::from_secs(4));
    g.bench_function("features_640x480", |b| {
        b.iter(|| RgbdFeatures::new(w, h, black_box(&raw), &depth, None, &cfg).unwrap());
    });
    let f = RgbdFeatures::new(w, h, &raw, &depth, None, &cfg).unwrap();
    // the peer's template box A (60, 150, 100, 200) and candidate B
    let a = BBox::from_ltwh(60.0, 150.0, 100.0, 200.0);
    let bb = BBox::from_ltwh(300.0, 170.0, 100.0, 200.0);
    let m = PatchMultiCueModel::new(cfg, &f, &a, &a).unwrap();
    g.bench_function("patch_descriptor_100x200", |b| {
        b.iter(|| m.score_descriptor(&m.describe_box(&f, black_box(&bb)).unwrap()));
    });
    g.finish();
}

fn step(c: &mut Criterion) {
    let scene = RgbdScene::new(ScenarioId::S1StaticOcclusion, 0).unwrap();
    // frames 90-92: the target walks (t = 3 s), so the MEKF candidate is off the G1 centre
    let s0 = scene.render(90).unwrap();
    let s1 = scene.render(91).unwrap();
    let s2 = scene.render(92).unwrap();
    let f0 = RgbdFrame::new(640, 480, s0.rgb, s0.depth_m, EgoMotion::None).unwrap();
    let f1 = RgbdFrame::new(640, 480, s1.rgb, s1.depth_m, EgoMotion::None).unwrap();
    let f2 = RgbdFrame::new(640, 480, s2.rgb, s2.depth_m, EgoMotion::None).unwrap();
    let mut g = c.benchmark_group("rgbd");
    g.sample_size(20).measurement_time(Duration::from_secs(5));
    for (name, stride) in [("step_640x480_k54", 1u32), ("step_640x480_k54_stride2", 2)] {
        let mut cfg = RgbdPersonConfig::paper();
        cfg.model.stride = stride;
        let mut tr = RgbdPersonTracker::new(cfg).unwrap();
        tr.init(
            Stamp::from_frame(90, scene.dt),
            &f0,
            s0.truth.amodal.unwrap(),
        )
        .unwrap();
        // K is printed (54 unless the MEKF candidate falls on a G1 centre)
        tr.step(Stamp::from_frame(91, scene.dt), &f1).unwrap();
        let probe = tr
            .clone()
            .step(Stamp::from_frame(92, scene.dt), &f2)
            .unwrap();
        eprintln!("{name}: {} candidates", probe.n_candidates);
        g.bench_function(name, |b| {
            b.iter_batched(
                || tr.clone(),
                |mut t| {
                    t.step(Stamp::from_frame(92, scene.dt), black_box(&f2))
                        .unwrap()
                },
                BatchSize::SmallInput,
            );
        });
    }
    g.finish();
}

criterion_group!(benches, descriptor, step);
criterion_main!(benches);
