//! Scores of a SLAM run against ground truth, with the definitions that the Python peers
//! (`benches/peers/mrclam_peers.py`) use too (docs/slamot.md, "Scores"):
//!
//! - robot error: mean (and max) over the scoring epochs of the Euclidean position error, no
//!   alignment ([`TrajectoryScore::mean`], [`TrajectoryScore::max`]);
//! - ATE: root-mean-square position error, without alignment ([`TrajectoryScore::ate_rmse`]) and
//!   after the least-squares rigid SE(2) transform (rotation + translation, no scale; closed form
//!   of Horn / Umeyama in the plane) of the estimated positions onto the truth
//!   ([`TrajectoryScore::ate_rmse_aligned`], the transform in [`TrajectoryScore::alignment`]);
//! - map error: mean Euclidean error of the landmarks in the estimated map (no alignment, and with
//!   the trajectory's alignment applied) ([`score_map`]);
//! - target OSPA / GOSPA per epoch ([`score_targets`]) and association accuracy (in
//!   [`run_mrclam`](super::run_mrclam)).
//!
//! ```
//! use quarry_repro::slamot::score_trajectory;
//! let truth = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
//! let est = [[0.0, 0.1, 0.0], [1.0, 0.1, 0.0], [2.0, 0.1, 0.0]]; // shifted 0.1 m in y
//! let s = score_trajectory(&est, &truth)?;
//! assert!((s.mean - 0.1).abs() < 1e-12 && (s.ate_rmse - 0.1).abs() < 1e-12);
//! assert!(s.ate_rmse_aligned < 1e-12); // a rigid shift is aligned away
//! # Ok::<(), quarry_repro::ReproError>(())
//! ```

use quarry_core::LandmarkId;
use serde::{Deserialize, Serialize};

use crate::{ReproError, Result};

/// A rigid transform of the plane: `p ↦ R(theta) p + (tx, ty)`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Se2 {
    /// Translation x \[m\].
    pub tx: f64,
    /// Translation y \[m\].
    pub ty: f64,
    /// Rotation \[rad\].
    pub theta: f64,
}

impl Se2 {
    /// Applies the transform to a point.
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.theta.sin_cos();
        [c * p[0] - s * p[1] + self.tx, s * p[0] + c * p[1] + self.ty]
    }
}

/// Scores of an estimated trajectory against the truth at the same epochs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryScore {
    /// Epochs scored.
    pub epochs: usize,
    /// Mean position error, no alignment \[m\] ("robot error").
    pub mean: f64,
    /// Largest position error, no alignment \[m\].
    pub max: f64,
    /// RMS position error, no alignment \[m\].
    pub ate_rmse: f64,
    /// RMS position error after [`Self::alignment`] \[m\].
    pub ate_rmse_aligned: f64,
    /// The least-squares rigid transform of the estimate onto the truth.
    pub alignment: Se2,
}

/// The least-squares rigid SE(2) transform `T` minimising `Σ |T(est_k) − truth_k|²` (no scale).
/// Errors when the lengths differ, either is empty, or a value is not finite.
pub fn align_se2(est: &[[f64; 2]], truth: &[[f64; 2]]) -> Result<Se2> {
    check_pairs(est.len(), truth.len())?;
    if est.iter().chain(truth).flatten().any(|v| !v.is_finite()) {
        return Err(ReproError::Invalid(
            "trajectory: non-finite position".into(),
        ));
    }
    let n = est.len() as f64;
    let mean = |v: &[[f64; 2]]| {
        let s = v.iter().fold([0.0, 0.0], |a, p| [a[0] + p[0], a[1] + p[1]]);
        [s[0] / n, s[1] / n]
    };
    let (me, mt) = (mean(est), mean(truth));
    let (mut c, mut s) = (0.0, 0.0);
    for (a, b) in est.iter().zip(truth) {
        let (ax, ay) = (a[0] - me[0], a[1] - me[1]);
        let (bx, by) = (b[0] - mt[0], b[1] - mt[1]);
        c += ax * bx + ay * by;
        s += ax * by - ay * bx;
    }
    let theta = if c == 0.0 && s == 0.0 {
        0.0
    } else {
        s.atan2(c)
    };
    let r = Se2 {
        tx: 0.0,
        ty: 0.0,
        theta,
    }
    .apply(me);
    Ok(Se2 {
        tx: mt[0] - r[0],
        ty: mt[1] - r[1],
        theta,
    })
}

fn check_pairs(a: usize, b: usize) -> Result<()> {
    if a != b {
        return Err(ReproError::Invalid(format!(
            "trajectory: {a} estimates but {b} truth poses"
        )));
    }
    if a == 0 {
        return Err(ReproError::Invalid("trajectory: no epochs to score".into()));
    }
    Ok(())
}

/// Scores estimated poses `[x, y, θ]` against the true poses at the same epochs (the headings
/// are not scored; the alignment is fitted on positions).
pub fn score_trajectory(est: &[[f64; 3]], truth: &[[f64; 3]]) -> Result<TrajectoryScore> {
    check_pairs(est.len(), truth.len())?;
    let e: Vec<[f64; 2]> = est.iter().map(|p| [p[0], p[1]]).collect();
    let t: Vec<[f64; 2]> = truth.iter().map(|p| [p[0], p[1]]).collect();
    let al = align_se2(&e, &t)?;
    let n = e.len() as f64;
    let d = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let errs: Vec<f64> = e.iter().zip(&t).map(|(a, b)| d(*a, *b)).collect();
    let sq_al: f64 = e
        .iter()
        .zip(&t)
        .map(|(a, b)| d(al.apply(*a), *b).powi(2))
        .sum();
    Ok(TrajectoryScore {
        epochs: e.len(),
        mean: errs.iter().sum::<f64>() / n,
        max: errs.iter().copied().fold(0.0, f64::max),
        ate_rmse: (errs.iter().map(|v| v * v).sum::<f64>() / n).sqrt(),
        ate_rmse_aligned: (sq_al / n).sqrt(),
        alignment: al,
    })
}

/// Map scores: the landmarks of `est` that have a true position.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MapScore {
    /// Landmarks scored.
    pub landmarks: usize,
    /// Mean landmark position error, no alignment \[m\] (NaN with no landmark).
    pub mean: f64,
    /// Mean landmark position error after the given alignment \[m\].
    pub mean_aligned: f64,
}

/// Scores an estimated map against the true landmark positions; `alignment` (usually the
/// trajectory's, [`TrajectoryScore::alignment`]) gives [`MapScore::mean_aligned`].
pub fn score_map(
    est: &[(LandmarkId, [f64; 2])],
    truth: &[(LandmarkId, [f64; 2])],
    alignment: Se2,
) -> MapScore {
    let d = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let (mut n, mut s, mut sa) = (0usize, 0.0, 0.0);
    for (id, m) in est {
        if let Some((_, t)) = truth.iter().find(|(i, _)| i == id) {
            n += 1;
            s += d(*m, *t);
            sa += d(alignment.apply(*m), *t);
        }
    }
    let nf = n as f64;
    MapScore {
        landmarks: n,
        mean: if n > 0 { s / nf } else { f64::NAN },
        mean_aligned: if n > 0 { sa / nf } else { f64::NAN },
    }
}

/// One epoch's target sets: (true positions, estimated positions).
pub type TargetEpoch = (Vec<[f64; 2]>, Vec<[f64; 2]>);

/// Mean OSPA and GOSPA (p = 2, cut-off `c`) over epochs of (true positions, estimated
/// positions); (NaN, NaN) with no epoch.
pub fn score_targets(epochs: &[TargetEpoch], c: f64) -> Result<(f64, f64)> {
    if epochs.is_empty() {
        return Ok((f64::NAN, f64::NAN));
    }
    let (mut o, mut g) = (0.0, 0.0);
    for (truth, est) in epochs {
        o += quarry_eval::ospa::ospa(truth, est, 2.0, c)?;
        g += quarry_eval::ospa::gospa(truth, est, 2.0, c)?.distance;
    }
    let n = epochs.len() as f64;
    Ok((o / n, g / n))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rot(p: [f64; 3], t: Se2) -> [f64; 3] {
        let q = t.apply([p[0], p[1]]);
        [q[0], q[1], p[2] + t.theta]
    }

    #[test]
    fn a_rigidly_moved_trajectory_aligns_to_zero() {
        let truth: Vec<[f64; 3]> = (0..50)
            .map(|k| {
                let s = f64::from(k) * 0.2;
                [3.0 * s.cos(), 2.0 * s.sin() + 0.1 * s, s]
            })
            .collect();
        let t = Se2 {
            tx: 1.5,
            ty: -0.7,
            theta: 0.4,
        };
        let est: Vec<[f64; 3]> = truth.iter().map(|p| rot(*p, t)).collect();
        let s = score_trajectory(&est, &truth).unwrap();
        assert!(s.ate_rmse_aligned < 1e-9, "{s:?}");
        assert!(s.mean > 0.5 && s.ate_rmse >= s.mean && s.max >= s.ate_rmse);
        // the fitted transform is the inverse of t
        assert!((s.alignment.theta + 0.4).abs() < 1e-9, "{s:?}");
        for (e, tr) in est.iter().zip(&truth) {
            let q = s.alignment.apply([e[0], e[1]]);
            assert!((q[0] - tr[0]).abs() < 1e-9 && (q[1] - tr[1]).abs() < 1e-9);
        }
    }

    #[test]
    fn hand_made_errors() {
        // errors 0, 0.3, 0.4 (a 3-4-5 triangle scaled by 0.1) at three epochs
        let truth = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        let est = [[0.0, 0.0, 0.0], [1.3, 0.0, 0.0], [2.0, 0.4, 0.0]];
        let s = score_trajectory(&est, &truth).unwrap();
        assert_eq!(s.epochs, 3);
        assert!((s.mean - 0.7 / 3.0).abs() < 1e-12);
        assert!((s.max - 0.4).abs() < 1e-12);
        assert!((s.ate_rmse - (0.25_f64 / 3.0).sqrt()).abs() < 1e-12);
        // alignment can only reduce the RMS error (the identity is a candidate)
        assert!(s.ate_rmse_aligned <= s.ate_rmse + 1e-12);
        assert!(s.ate_rmse_aligned > 0.0);
    }

    #[test]
    fn map_scores_only_known_landmarks() {
        let truth = vec![(LandmarkId(0), [1.0, 1.0]), (LandmarkId(1), [5.0, 0.0])];
        let est = vec![
            (LandmarkId(0), [1.0, 1.5]),
            (LandmarkId(1), [5.0, 0.1]),
            (LandmarkId(9), [0.0, 0.0]),
        ];
        let m = score_map(&est, &truth, Se2::default());
        assert_eq!(m.landmarks, 2);
        assert!((m.mean - 0.3).abs() < 1e-12 && (m.mean_aligned - 0.3).abs() < 1e-12);
        let shift = Se2 {
            tx: 0.0,
            ty: -0.5,
            theta: 0.0,
        };
        let m = score_map(&est, &truth, shift);
        assert!((m.mean_aligned - 0.2).abs() < 1e-12, "{m:?}");
        assert!(score_map(&[], &truth, shift).mean.is_nan());
    }

    #[test]
    fn targets_ospa_gospa() {
        // one epoch: one target found 0.3 m off, one missed; c = 1
        let ep = vec![(vec![[0.0, 0.0], [5.0, 5.0]], vec![[0.3, 0.0]])];
        let (o, g) = score_targets(&ep, 1.0).unwrap();
        assert!((o - f64::midpoint(0.09, 1.0).sqrt()).abs() < 1e-12, "{o}");
        assert!((g - (0.09 + 0.5_f64).sqrt()).abs() < 1e-12, "{g}");
        assert!(score_targets(&[], 1.0).unwrap().0.is_nan());
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(score_trajectory(&[], &[]).is_err());
        assert!(score_trajectory(&[[0.0; 3]], &[[0.0; 3], [1.0; 3]]).is_err());
        assert!(score_trajectory(&[[f64::NAN, 0.0, 0.0]], &[[0.0; 3]]).is_err());
    }
}
