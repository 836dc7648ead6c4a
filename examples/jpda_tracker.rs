//! The stand-alone JPDA / JIPDA tracker (`quarry::trackers::cv_jpda`) on the shared
//! `bench-data/jpda_n{3,10,20}_meas.csv` scenarios (100 scans, P_D 0.9, Poisson(10) clutter).
//!
//! Two runs per scenario:
//! - *known*: one JPDA track per target, started from the truth at scan 0 (the workload of the
//!   Stone Soup peer, `peers/bench_jpda.py`): position RMSE over all targets and scans;
//! - *unknown*: JIPDA with birth from unexplained detections and existence-based
//!   confirmation/deletion: mean OSPA (c = 5 m, p = 2) of the confirmed tracks, and the number
//!   of confirmed tracks at the last scan.
//!
//! Run: `cargo run --release --example jpda_tracker` (data from `$QUARRY_SHARED/bench-data` or
//! `../shared/bench-data`; skipped with a message when absent).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{DMatrix, Matrix4, Vector4};
use quarry::assoc::assign::hungarian;
use quarry::core::{Gaussian, MultiTargetTracker, Stamp, TimeUs};
use quarry::trackers::cv_jpda::{AssocMode, JpdaTracker, JpdaTrackerConfig};
use std::path::{Path, PathBuf};

fn data_dir() -> Option<PathBuf> {
    let base = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    let d = base.join("bench-data");
    d.join("jpda_n3_meas.csv").exists().then_some(d)
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

/// truth[scan][target] = [x, y, vx, vy]; scans[scan] = detections.
type Truth = Vec<Vec<[f64; 4]>>;
type Scans = Vec<Vec<[f64; 2]>>;

fn load(dir: &Path, n: usize) -> (Truth, Scans) {
    let tr = rows(&dir.join(format!("jpda_n{n}_truth.csv")));
    let me = rows(&dir.join(format!("jpda_n{n}_meas.csv")));
    let scans = tr.iter().map(|r| r[0] as usize).max().unwrap() + 1;
    let mut truth = vec![vec![[0.0; 4]; n]; scans];
    for r in &tr {
        truth[r[0] as usize][r[1] as usize] = [r[2], r[3], r[4], r[5]];
    }
    let mut dets = vec![Vec::new(); scans];
    for r in &me {
        dets[r[0] as usize].push([r[1], r[2]]);
    }
    (truth, dets)
}

fn ospa(est: &[[f64; 2]], truth: &[[f64; 4]], c: f64) -> f64 {
    let (m, n) = (est.len(), truth.len());
    if m == 0 && n == 0 {
        return 0.0;
    }
    let d = DMatrix::from_fn(m, n, |i, j| {
        let dx = est[i][0] - truth[j][0];
        let dy = est[i][1] - truth[j][1];
        (dx * dx + dy * dy).min(c * c)
    });
    let a = hungarian(&d).unwrap();
    let big = m.max(n) as f64;
    ((a.cost + c * c * (m.abs_diff(n)) as f64) / big).sqrt()
}

fn main() {
    let Some(dir) = data_dir() else {
        println!("skipped: bench-data not found (set QUARRY_SHARED)");
        return;
    };
    for n in [3usize, 10, 20] {
        let (truth, dets) = load(&dir, n);
        // Known targets, JPDA (Stone Soup's "known n" workload).
        let cfg = JpdaTrackerConfig {
            mode: AssocMode::Jpda,
            ..Default::default()
        };
        let p0 = Matrix4::from_diagonal(&Vector4::new(0.25, 0.25, 0.05, 0.05));
        let init: Vec<Gaussian<4>> = truth[0]
            .iter()
            .map(|t| Gaussian::try_new(Vector4::new(t[0], t[1], t[2], t[3]), p0).unwrap())
            .collect();
        let mut trk = JpdaTracker::with_tracks(cfg, &init, TimeUs(0)).unwrap();
        let t0 = std::time::Instant::now();
        let (mut se, mut cnt) = (0.0, 0usize);
        let mut held = 0;
        for (k, z) in dets.iter().enumerate() {
            let out = trk.step(Stamp::from_frame(k as u64, 1.0), z).unwrap();
            for r in &out {
                let p = r.xy().unwrap();
                let t = truth[k][r.id.0 as usize];
                let e2 = (p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2);
                se += e2;
                cnt += 1;
                if k + 1 == dets.len() && e2.sqrt() < 2.0 {
                    held += 1;
                }
            }
        }
        let per_scan = t0.elapsed().as_secs_f64() / dets.len() as f64;
        println!(
            "n={n:2} known  JPDA : position RMSE {:.4} m, {held}/{n} tracks held, {:.1} us/scan",
            (se / cnt as f64).sqrt(),
            per_scan * 1e6
        );
        // Unknown count, JIPDA with birth and existence thresholds.
        let mut trk = JpdaTracker::new(JpdaTrackerConfig::default()).unwrap();
        let t0 = std::time::Instant::now();
        let (mut o, mut last) = (0.0, 0);
        for (k, z) in dets.iter().enumerate() {
            let out = trk.step(Stamp::from_frame(k as u64, 1.0), z).unwrap();
            let est: Vec<[f64; 2]> = out.iter().map(|r| r.xy().unwrap()).collect();
            o += ospa(&est, &truth[k], 5.0);
            last = out.len();
        }
        let per_scan = t0.elapsed().as_secs_f64() / dets.len() as f64;
        println!(
            "n={n:2} birth JIPDA: mean OSPA(c=5, p=2) {:.3} m, {last} confirmed tracks at the end (truth {n}), {:.1} us/scan",
            o / dets.len() as f64,
            per_scan * 1e6
        );
    }
}
