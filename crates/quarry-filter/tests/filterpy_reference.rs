//! Our KF and EKF on `shared/bench-data` reproduce filterpy's final states.
//!
//! Reference numbers: computed once with filterpy 2.0.0 in the peer venv
//! (`~/.cache/quarry-peers-venv`), replaying `kf_track.csv` with `KalmanFilter` and `ekf_rb.csv`
//! with `ExtendedKalmanFilter` exactly as `shared/peers/bench_kf.py` / `bench_ekf.py` do (both use
//! the Joseph form), and printing the final `x` and `P` (order [x, vx, y, vy]) with `repr`.
//! Skipped (with a message) when the shared data are absent.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{Matrix2, Matrix4, Vector2, Vector4};
use quarry_core::{Gaussian, Pose2};
use quarry_filter::{ConstantVelocity2, Ekf, Position2, RangeBearingCv};
use std::path::PathBuf;

const KF_X: [f64; 4] = [
    -275.61775140543256,
    -3.1444357560297584,
    373.2838771155796,
    8.044739160375855,
];
const KF_P: [f64; 16] = [
    0.06462304038131697,
    0.09627485643164652,
    0.0,
    0.0,
    0.09627485643164652,
    0.31061743313114254,
    0.0,
    0.0,
    0.0,
    0.0,
    0.06462304038131697,
    0.09627485643164652,
    0.0,
    0.0,
    0.09627485643164652,
    0.31061743313114254,
];
const EKF_X: [f64; 4] = [
    0.45680218736622613,
    -0.581880316953651,
    129.89286175086303,
    1.8984914676108018,
];
const EKF_P: [f64; 16] = [
    0.11138010079188003,
    0.039270791845481844,
    -0.000489879877330036,
    -6.537669293336831e-05,
    0.03927079184548186,
    0.027879552629665436,
    -0.00014951878796890658,
    -7.158121863418835e-05,
    -0.0004898798773300359,
    -0.00014951878796890647,
    0.026596766296223286,
    0.014947508144775577,
    -6.537669293336822e-05,
    -7.158121863418816e-05,
    0.014947508144775572,
    0.01729315219773748,
];

fn data_dir() -> Option<PathBuf> {
    let base = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
        PathBuf::from,
    );
    let d = base.join("bench-data");
    if d.join("kf_track.csv").exists() {
        Some(d)
    } else {
        eprintln!("skipping: no shared bench-data at {}", d.display());
        None
    }
}

/// Columns of a headed CSV by name.
fn read_cols(path: &PathBuf, names: &[&str]) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| header.iter().position(|h| h == n).unwrap())
        .collect();
    let mut out = vec![Vec::new(); names.len()];
    for line in lines.filter(|l| !l.is_empty()) {
        let f: Vec<&str> = line.split(',').collect();
        for (o, &i) in out.iter_mut().zip(&idx) {
            o.push(f[i].parse().unwrap());
        }
    }
    out
}

/// [x, vx, y, vy] (peer order) → [x, y, vx, vy] (ours).
const PERM: [usize; 4] = [0, 2, 1, 3];

fn to_ours(x: &[f64; 4], p: &[f64; 16]) -> (Vector4<f64>, Matrix4<f64>) {
    let xm = Vector4::from_fn(|i, _| x[PERM[i]]);
    let pm = Matrix4::from_fn(|i, j| p[PERM[i] * 4 + PERM[j]]);
    (xm, pm)
}

#[test]
fn kf_matches_filterpy() {
    let Some(dir) = data_dir() else { return };
    let c = read_cols(&dir.join("kf_track.csv"), &["zx", "zy"]);
    let x0 = Gaussian::try_new(Vector4::new(0.0, 0.0, 1.0, 0.5), Matrix4::identity()).unwrap();
    let mut kf = Ekf::new(
        x0,
        ConstantVelocity2::cwna(0.5).unwrap(),
        Position2::isotropic(0.5).unwrap(),
    )
    .unwrap();
    for (zx, zy) in c[0].iter().zip(&c[1]) {
        kf.predict(&(), 0.1).unwrap();
        kf.update(&Vector2::new(*zx, *zy)).unwrap();
    }
    let (x, p) = to_ours(&KF_X, &KF_P);
    assert!((kf.mean() - x).amax() < 1e-9, "{} vs {x}", kf.mean());
    assert!((kf.cov() - p).amax() < 1e-12, "{} vs {p}", kf.cov());
}

#[test]
fn ekf_matches_filterpy() {
    let Some(dir) = data_dir() else { return };
    let c = read_cols(&dir.join("ekf_rb.csv"), &["range", "bearing"]);
    let x0 = Gaussian::try_new(
        Vector4::new(40.0, 10.0, 0.5, 1.0),
        Matrix4::from_diagonal(&Vector4::new(4.0, 4.0, 1.0, 1.0)),
    )
    .unwrap();
    let rb = RangeBearingCv::new(Pose2::identity(), 0.5, 0.01).unwrap();
    assert_eq!(rb.point.r, Matrix2::new(0.25, 0.0, 0.0, 1e-4));
    let mut ekf = Ekf::new(x0, ConstantVelocity2::cwna(0.01).unwrap(), rb).unwrap();
    for (r, b) in c[0].iter().zip(&c[1]) {
        ekf.predict(&(), 0.1).unwrap();
        ekf.update(&Vector2::new(*r, *b)).unwrap();
    }
    let (x, p) = to_ours(&EKF_X, &EKF_P);
    assert!((ekf.mean() - x).amax() < 1e-9, "{} vs {x}", ekf.mean());
    assert!((ekf.cov() - p).amax() < 1e-12, "{} vs {p}", ekf.cov());
}
