//! MOT metric benchmarks: CLEAR MOT + IDF1 + HOTA in one pass (`MotEvaluation::new` +
//! `summary`, i.e. pairwise IoU, the per-frame assignments and all three metric families) on
//! `../shared/bench-data/mot_gt.csv` vs `mot_hyp.csv` (60 frames, 4 objects) and on PETS09-S2L1
//! ground truth (200 frames, 1222 boxes) vs a deterministic perturbation of itself. Compare with
//! `peers/bench_motmetrics.py` (py-motmetrics + TrackEval on the same pair).
//!
//! `cargo bench --bench eval -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::collections::BTreeMap;
use std::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use quarry::eval::motchallenge::{GtStyle, MotRow, read_gt_file, to_frames};
use quarry::eval::{Euclidean, Frame, Iou, Ltwh, MotEvaluation, Similarity};

fn shared() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    if p.join("bench-data/mot_gt.csv").exists() {
        Some(p)
    } else {
        eprintln!("skipping eval benches: no bench-data at {}", p.display());
        None
    }
}

fn bench_pair(sh: &std::path::Path) -> Vec<Frame<Ltwh>> {
    let mut by_frame: BTreeMap<u64, Frame<Ltwh>> = BTreeMap::new();
    for (name, is_gt) in [("mot_gt.csv", true), ("mot_hyp.csv", false)] {
        let text = std::fs::read_to_string(sh.join("bench-data").join(name)).unwrap();
        for l in text.lines().skip(1) {
            let c: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            let f = by_frame.entry(c[0] as u64).or_default();
            let side = if is_gt { &mut f.gt } else { &mut f.hyp };
            side.push((c[1] as i64, [c[2], c[3], c[4], c[5]]));
        }
    }
    by_frame.into_values().collect()
}

/// Same deterministic perturbation as crates/quarry-eval/tests/mot_fixtures.rs.
fn pets_pair(sh: &std::path::Path) -> Vec<Frame<Ltwh>> {
    let gt = read_gt_file(sh.join("data/pets09-s2l1/gt.txt"), GtStyle::Auto).unwrap();
    let mut res = Vec::new();
    for g in &gt {
        let (fi, ii) = (g.frame as i64, g.id);
        if (fi + 3 * ii) % 17 == 0 {
            continue;
        }
        let mut dx = ((fi * 7 + ii * 13) % 11 - 5) as f64 * 0.9;
        let dy = ((fi * 5 + ii * 3) % 9 - 4) as f64 * 0.8;
        let s = 1.0 + ((fi + ii) % 5 - 2) as f64 * 0.03;
        let mut hid = ii;
        if fi > 120 && ii % 4 == 1 {
            hid = ii + 1000;
        }
        if (60..80).contains(&fi) && (ii == 15 || ii == 19) {
            hid = 34 - ii;
        }
        if fi % 23 == 0 && ii % 2 == 0 {
            dx += 25.0;
        }
        let b = g.bbox;
        res.push(MotRow {
            frame: g.frame,
            id: hid,
            bbox: [b[0] + dx, b[1] + dy, b[2] * s, b[3] * s],
            conf: 1.0,
            extra: [None; 3],
        });
    }
    to_frames(&gt, &res, 0.5).unwrap()
}

struct CentreDistance(Euclidean);

fn centre(b: &Ltwh) -> [f64; 2] {
    [b[0] + b[2] / 2.0, b[1] + b[3] / 2.0]
}

impl Similarity<Ltwh> for CentreDistance {
    fn distance(&self, gt: &Ltwh, hyp: &Ltwh) -> Option<f64> {
        self.0.distance(&centre(gt), &centre(hyp))
    }
    fn similarity(&self, gt: &Ltwh, hyp: &Ltwh) -> f64 {
        self.0.similarity(&centre(gt), &centre(hyp))
    }
}

fn metrics(c: &mut Criterion) {
    let Some(sh) = shared() else { return };
    let pair = bench_pair(&sh);
    let pets = pets_pair(&sh);
    let iou = Iou::default();
    let dist = CentreDistance(Euclidean::new(20.0).unwrap());
    let mut g = c.benchmark_group("mot_metrics");
    g.bench_function("bench_pair_iou_clear_idf1_hota", |b| {
        b.iter(|| {
            MotEvaluation::new(black_box(&pair), &iou)
                .unwrap()
                .summary()
                .unwrap()
        });
    });
    g.bench_function("bench_pair_dist_clear_idf1_hota", |b| {
        b.iter(|| {
            MotEvaluation::new(black_box(&pair), &dist)
                .unwrap()
                .summary()
                .unwrap()
        });
    });
    g.bench_function("bench_pair_iou_clear_only", |b| {
        b.iter(|| {
            MotEvaluation::new(black_box(&pair), &iou)
                .unwrap()
                .clear_mot()
                .unwrap()
        });
    });
    g.bench_function("pets09_iou_clear_idf1_hota", |b| {
        b.iter(|| {
            MotEvaluation::new(black_box(&pets), &iou)
                .unwrap()
                .summary()
                .unwrap()
        });
    });
    g.finish();
}

criterion_group!(benches, metrics);
criterion_main!(benches);
