//! Two-point target initiation (spec A19), shared by the RBPF and the EKF-SLAMOT baseline so
//! that both initiate targets by the same rule.

use nalgebra::{Matrix2, SMatrix, Vector2, Vector4};
use quarry_core::{CoreError, Gaussian};

use crate::TrackerError;

/// Detections placed in the map frame: (mean, covariance) per detection.
pub(crate) type MapPoints = Vec<(Vector2<f64>, Matrix2<f64>)>;

/// A previous-epoch detection in the map frame (mean, covariance) and the time since it [s].
#[derive(Debug, Clone, Copy)]
pub(crate) struct InitPartner {
    pub(crate) p: Vector2<f64>,
    pub(crate) cov: Matrix2<f64>,
    pub(crate) dt: f64,
}

/// Two-point initiation (spec A19): state [p_k, (p_k − p_{k−1})/Δt] with the covariance of that
/// linear map of the two independent points, then fused (Kalman update, H = [0 I]) with the
/// velocity prior N(0, σ_v0² I) of §2.12.
pub(crate) fn two_point_state(
    p: Vector2<f64>,
    cov: Matrix2<f64>,
    prev: &InitPartner,
    sigma_v0: f64,
) -> Result<Gaussian<4>, TrackerError> {
    two_point_gaussian(p, cov, prev.p, prev.cov, prev.dt, sigma_v0)
}

/// [`two_point_state`] on plain values (shared with the EKF baseline).
pub(crate) fn two_point_gaussian(
    p: Vector2<f64>,
    cov: Matrix2<f64>,
    prev_p: Vector2<f64>,
    prev_cov: Matrix2<f64>,
    dt: f64,
    sigma_v0: f64,
) -> Result<Gaussian<4>, TrackerError> {
    let v = (p - prev_p) / dt;
    let mut m = Vector4::new(p.x, p.y, v.x, v.y);
    let mut c = SMatrix::<f64, 4, 4>::zeros();
    c.fixed_view_mut::<2, 2>(0, 0).copy_from(&cov);
    c.fixed_view_mut::<2, 2>(0, 2).copy_from(&(cov / dt));
    c.fixed_view_mut::<2, 2>(2, 0).copy_from(&(cov / dt));
    c.fixed_view_mut::<2, 2>(2, 2)
        .copy_from(&((cov + prev_cov) / (dt * dt)));
    // fuse with the prior v ~ N(0, σ_v0² I): z = 0, H = [0 I], R = σ_v0² I
    let s = c.fixed_view::<2, 2>(2, 2).into_owned() + Matrix2::identity() * sigma_v0 * sigma_v0;
    let s_inv = s.try_inverse().ok_or(CoreError::NotPositiveDefinite {
        what: "two-point initiation covariance",
    })?;
    let k = c.fixed_view::<4, 2>(0, 2).into_owned() * s_inv;
    m -= k * Vector2::new(m[2], m[3]);
    c -= k * c.fixed_view::<2, 4>(2, 0).into_owned();
    let c = (c + c.transpose()) * 0.5;
    Ok(Gaussian::try_new(m, c)?)
}

/// Two-point initiation (spec A19): pairs this epoch's map-frame detections `pts` with the
/// previous epoch's `prev` (`dt` seconds earlier). A pair is gated by
/// `max_speed · dt + 3 √(tr Σ_j + tr Σ_i)`; pairs are taken nearest first, each point at most
/// once. Returns `(j, i)` (current, previous) sorted by `j`. Shared by the RBPF and the
/// EKF-SLAMOT baseline so that both initiate targets by the same rule.
pub(crate) fn two_point_pairs(
    pts: &[(Vector2<f64>, Matrix2<f64>)],
    prev: &[(Vector2<f64>, Matrix2<f64>)],
    dt: f64,
    max_speed: f64,
) -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    for (j, (pj, cj)) in pts.iter().enumerate() {
        for (i, (pi, ci)) in prev.iter().enumerate() {
            let d = (pj - pi).norm();
            let gate = max_speed * dt + 3.0 * (cj.trace() + ci.trace()).sqrt();
            if d <= gate {
                pairs.push((d, j, i));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut used_j = vec![false; pts.len()];
    let mut used_i = vec![false; prev.len()];
    let mut out = Vec::new();
    for (_, j, i) in pairs {
        if !used_j[j] && !used_i[i] {
            used_j[j] = true;
            used_i[i] = true;
            out.push((j, i));
        }
    }
    out.sort_by_key(|&(j, _)| j);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TrackerConfig;
    use crate::slamot::{SlamotConfig, TargetInit};

    #[test]
    fn two_point_initiation() {
        // exact points, a vague velocity prior: the velocity is the difference quotient
        let cov = Matrix2::identity() * 1e-6;
        let prev = InitPartner {
            p: Vector2::new(1.0, 2.0),
            cov,
            dt: 0.2,
        };
        let g = two_point_state(Vector2::new(1.2, 1.9), cov, &prev, 100.0).unwrap();
        assert!((g.mean[2] - 1.0).abs() < 1e-6 && (g.mean[3] + 0.5).abs() < 1e-6);
        assert!((g.mean[0] - 1.2).abs() < 1e-9);
        // noisy points, a tight prior: the velocity shrinks towards 0 and its variance is
        // below both the prior's and the difference quotient's
        let cov = Matrix2::identity() * 0.09;
        let prev = InitPartner { cov, ..prev };
        let g = two_point_state(Vector2::new(1.2, 1.9), cov, &prev, 1.5).unwrap();
        let v_diff = 2.0 * 0.09 / 0.04;
        assert!(g.mean[2] > 0.0 && g.mean[2] < 1.0);
        assert!(g.cov[(2, 2)] < 1.5 * 1.5 && g.cov[(2, 2)] < v_diff);
        assert!(g.cov[(0, 0)] <= 0.09 + 1e-12);
        assert!((g.cov - g.cov.transpose()).amax() < 1e-12);
        assert!(g.cov.cholesky().is_some());
        // a bad configuration is an error
        let bad = SlamotConfig {
            target_init: TargetInit::TwoPoint {
                max_speed: f64::NAN,
            },
            ..SlamotConfig::default()
        };
        assert!(bad.validate().is_err());
    }
}
