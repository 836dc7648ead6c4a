//! Rao-Blackwellized particle-filter kernels.
//!
//! [`fastslam2`] holds the measurement proposal of FastSLAM 2.0 (Montemerlo et al. 2003; Thrun
//! et al., Probabilistic Robotics, Table 13.3): a particle's pose is drawn from its motion
//! Gaussian updated with the landmark measurements, and its weight is the measurements'
//! predictive likelihood under that Gaussian.
//!
//! [`fastslam1`] holds the per-particle FastSLAM 1.0 landmark kernels of spec 000 §2.5: each
//! particle carries its own map of landmark Gaussians in a [`LandmarkStore`] (use
//! [`crate::store::PersistentStore`] so that copying a particle at resampling is O(1) and a
//! landmark write O(log M)), and the measurement model is built for that particle's pose.
//!
//! [`LandmarkStore`]: quarry_core::LandmarkStore

/// FastSLAM 1.0 landmark initialisation and update (spec 000 §2.5).
///
/// ```
/// use nalgebra::Vector2;
/// use quarry_core::{Gaussian, LandmarkStore, Pose2};
/// use quarry_filter::{RangeBearing, UpdateForm, rbpf::fastslam1, store::PersistentStore};
/// let mut map: PersistentStore<Gaussian<2>> = PersistentStore::new();
/// let sensor = RangeBearing::new(Pose2::new(0.0, 0.0, 0.0), 0.1, 0.01)?; // this particle's pose
/// let id = fastslam1::landmark_init(&mut map, &sensor, &Vector2::new(5.0, 0.3))?;
/// let log_w = fastslam1::landmark_update(&mut map, id, &sensor, &Vector2::new(5.05, 0.31), UpdateForm::Joseph)?;
/// assert!(log_w.is_finite());
/// assert!(map.get(id).unwrap().cov[(0, 0)] < 0.01); // two fixes with σ_r = 0.1
/// # Ok::<(), quarry_filter::FilterError>(())
/// ```
pub mod fastslam1 {
    use crate::FilterError;
    use crate::ekf::{self, UpdateForm};
    use nalgebra::SVector;
    use quarry_core::{
        CoreError, Gaussian, InverseMeasurement, LandmarkId, LandmarkStore, MeasurementModel,
    };

    /// Initialises a new landmark from measurement `z` with the inverse model (for range-bearing:
    /// `m = s + r (cos(θ+b), sin(θ+b))`, `Σ = G_z R G_zᵀ`), appends it to `store` and returns its
    /// id. A new landmark contributes no weight factor (spec 000 §2.5). On error the store is
    /// unchanged.
    pub fn landmark_init<const D: usize, const Z: usize, M, S>(
        store: &mut S,
        model: &M,
        z: &SVector<f64, Z>,
    ) -> Result<LandmarkId, FilterError>
    where
        M: InverseMeasurement<D, Z> + ?Sized,
        S: LandmarkStore<Gaussian<D>>,
    {
        if !z.iter().all(|v| v.is_finite()) {
            return Err(FilterError::NonFiniteMeasurement);
        }
        let g = model.initialise(z)?;
        Ok(store.push(g))
    }

    /// Updates landmark `id` with measurement `z` (EKF, covariance by `form`; spec 000 uses
    /// Joseph) and returns the particle's log weight factor `ln N(ν; 0, S)`, evaluated with the
    /// landmark *before* the update. On error (unknown id, NaN, `S` not positive definite) the
    /// store is unchanged.
    pub fn landmark_update<const D: usize, const Z: usize, M, S>(
        store: &mut S,
        id: LandmarkId,
        model: &M,
        z: &SVector<f64, Z>,
        form: UpdateForm,
    ) -> Result<f64, FilterError>
    where
        M: MeasurementModel<D, Z> + ?Sized,
        S: LandmarkStore<Gaussian<D>>,
    {
        let prior = store.get(id).ok_or_else(|| {
            CoreError::invalid(
                "landmark id",
                format!("{} is not in the map (it holds {})", id.0, store.len()),
            )
        })?;
        let (post, inn) = ekf::update(prior, model, z, form)?;
        store.set(id, post)?;
        Ok(inn.log_likelihood())
    }
}

/// FastSLAM 2.0's measurement proposal for a planar pose `(x, y, θ)` and range-bearing
/// landmark measurements.
///
/// The proposal is the motion Gaussian `N(x̂, P)` (the motion model's mean and its linearised
/// covariance accumulated since the last update) conditioned on each measurement in turn with
/// an EKF step on the pose alone, the landmark's uncertainty folded into the noise:
/// `Q = R + H_m Σ_m H_mᵀ`, `S = H_x P H_xᵀ + Q`, `K = P H_xᵀ S⁻¹`. This is Table 13.3's
/// `Σ = (H_xᵀ Q⁻¹ H_x + P⁻¹)⁻¹`, `μ = x̂ + Σ H_xᵀ Q⁻¹ (z − ẑ)` in covariance form, which also
/// takes a singular `P` (a particle that has not moved: the update is then the identity and
/// the factor equals FastSLAM 1.0's). Each step returns `ln N(ν; 0, S)`, the factor of the
/// particle's importance weight; the pose is then drawn with [`sample_pose`](fastslam2::sample_pose) and the landmarks
/// updated at the drawn pose with [`fastslam1::landmark_update`] (whose factor is then not used).
///
/// ```
/// use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
/// use quarry_core::Gaussian;
/// use quarry_filter::rbpf::fastslam2;
/// let lm = Gaussian::try_new(Vector2::new(5.0, 0.0), Matrix2::identity() * 1e-4)?;
/// let r = Matrix2::new(0.01, 0.0, 0.0, 1e-4);
/// // the motion says x = 0 ± 0.3 m; the landmark 5 m ahead is seen at 4.8 m (± 0.1 m):
/// // x moves to 0.2 · 0.09 / (0.09 + 0.01) = 0.18
/// let (m, p) = (Vector3::zeros(), Matrix3::from_diagonal(&Vector3::new(0.09, 0.09, 1e-4)));
/// let u = fastslam2::pose_update(&m, &p, &lm, &Vector2::new(4.8, 0.0), &r)?;
/// assert!((u.mean.x - 0.18).abs() < 1e-3 && u.cov[(0, 0)] < 0.01 && u.log_likelihood.is_finite());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub mod fastslam2 {
    use crate::FilterError;
    use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector2, Vector3};
    use quarry_core::{Gaussian, wrap_angle};
    use rand::Rng;
    use rand_core::RngCore;
    use rand_distr::StandardNormal;

    const LN_2PI: f64 = 1.837_877_066_409_345_5;

    /// One conditioning step of the proposal.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct PoseUpdate {
        /// Posterior pose mean (heading wrapped).
        pub mean: Vector3<f64>,
        /// Posterior pose covariance (symmetric, Joseph form).
        pub cov: Matrix3<f64>,
        /// `ln N(ν; 0, S)`: the predictive log-likelihood, the weight factor.
        pub log_likelihood: f64,
        /// `νᵀ S⁻¹ ν` (χ² with 2 degrees of freedom when the model is right).
        pub nis: f64,
    }

    impl PoseUpdate {
        /// `ln N(ν; 0, S)` at another NIS value `d2` (for a robust gate).
        pub fn log_likelihood_at(&self, d2: f64) -> f64 {
            self.log_likelihood + 0.5 * (self.nis - d2)
        }
    }

    /// Conditions the pose Gaussian `N(mean, cov)` on one range-bearing measurement `z` of the
    /// landmark `lm` (noise `r`). Errors on non-finite input, a landmark at the pose, or `S`
    /// not positive definite.
    pub fn pose_update(
        mean: &Vector3<f64>,
        cov: &Matrix3<f64>,
        lm: &Gaussian<2>,
        z: &Vector2<f64>,
        r: &Matrix2<f64>,
    ) -> Result<PoseUpdate, FilterError> {
        if !z.iter().all(|v| v.is_finite()) {
            return Err(FilterError::NonFiniteMeasurement);
        }
        let dx = lm.mean.x - mean.x;
        let dy = lm.mean.y - mean.y;
        let q = dx * dx + dy * dy;
        if !(q.is_finite() && q > 1e-12) {
            return Err(FilterError::NonFiniteResult {
                what: "FastSLAM 2.0 proposal (landmark at the pose)",
            });
        }
        let rr = q.sqrt();
        let zhat = Vector2::new(rr, wrap_angle(dy.atan2(dx) - mean.z));
        let hm = Matrix2::new(dx / rr, dy / rr, -dy / q, dx / q);
        let hx = Matrix2x3::new(-dx / rr, -dy / rr, 0.0, dy / q, -dx / q, -1.0);
        let qn = r + hm * lm.cov * hm.transpose();
        let s = hx * cov * hx.transpose() + qn;
        let s = (s + s.transpose()) * 0.5;
        let chol = s
            .cholesky()
            .ok_or(FilterError::InnovationNotPositiveDefinite)?;
        let nu = Vector2::new(z.x - zhat.x, wrap_angle(z.y - zhat.y));
        let s_inv = chol.inverse();
        let k = cov * hx.transpose() * s_inv;
        let ikh = Matrix3::identity() - k * hx;
        let post = ikh * cov * ikh.transpose() + k * qn * k.transpose();
        let post = (post + post.transpose()) * 0.5;
        let mut m = mean + k * nu;
        m.z = wrap_angle(m.z);
        let l = chol.l();
        let log_det = 2.0 * (l[(0, 0)].ln() + l[(1, 1)].ln());
        let nis = (nu.transpose() * s_inv * nu)[(0, 0)];
        let log_lik = -0.5 * (nis + log_det + 2.0 * LN_2PI);
        if !(m.iter().chain(post.iter()).all(|v| v.is_finite()) && log_lik.is_finite()) {
            return Err(FilterError::NonFiniteResult {
                what: "FastSLAM 2.0 proposal",
            });
        }
        Ok(PoseUpdate {
            mean: m,
            cov: post,
            log_likelihood: log_lik,
            nis,
        })
    }

    /// Draws a pose from `N(mean, cov)` (`cov` symmetric positive semi-definite; a zero
    /// covariance returns the mean). The heading is wrapped.
    pub fn sample_pose(
        mean: &Vector3<f64>,
        cov: &Matrix3<f64>,
        rng: &mut dyn RngCore,
    ) -> Vector3<f64> {
        let l = psd_sqrt3(cov);
        let e = Vector3::new(
            rng.sample(StandardNormal),
            rng.sample(StandardNormal),
            rng.sample(StandardNormal),
        );
        let mut x = mean + l * e;
        x.z = wrap_angle(x.z);
        x
    }

    /// `L` with `L Lᵀ ≈ A` for a symmetric positive semi-definite 3×3 `A` (Cholesky with a
    /// vanishing jitter; the eigen-decomposition when that fails).
    fn psd_sqrt3(a: &Matrix3<f64>) -> Matrix3<f64> {
        let a = (a + a.transpose()) * 0.5;
        if a.iter().all(|v| *v == 0.0) {
            return Matrix3::zeros();
        }
        let jitter = 1e-15 * a.trace().abs().max(1e-300);
        if let Some(c) = (a + Matrix3::identity() * jitter).cholesky() {
            return c.l();
        }
        let e = a.symmetric_eigen();
        let d = e.eigenvalues.map(|v| v.max(0.0).sqrt());
        e.eigenvectors * Matrix3::from_diagonal(&d)
    }
}

#[cfg(test)]
mod tests {
    use super::fastslam1;
    use crate::store::{PersistentStore, VecStore};
    use crate::{RangeBearing, UpdateForm, ekf};
    use nalgebra::Vector2;
    use quarry_core::{Gaussian, LandmarkId, LandmarkStore, Pose2};

    #[test]
    fn kernels_match_ekf_and_keep_state_on_error() {
        let mut ps: PersistentStore<Gaussian<2>> = PersistentStore::new();
        let mut vs: VecStore<Gaussian<2>> = VecStore::new();
        let m = RangeBearing::new(Pose2::new(1.0, -1.0, 0.3), 0.2, 0.02).unwrap();
        let z0 = Vector2::new(4.0, 0.5);
        let a = fastslam1::landmark_init(&mut ps, &m, &z0).unwrap();
        let b = fastslam1::landmark_init(&mut vs, &m, &z0).unwrap();
        assert_eq!(a, b);
        let prior = *ps.get(a).unwrap();
        let z1 = Vector2::new(4.1, 0.52);
        let (post, inn) = ekf::update(&prior, &m, &z1, UpdateForm::Joseph).unwrap();
        let lw = fastslam1::landmark_update(&mut ps, a, &m, &z1, UpdateForm::Joseph).unwrap();
        let lw2 = fastslam1::landmark_update(&mut vs, b, &m, &z1, UpdateForm::Joseph).unwrap();
        assert_eq!(lw, inn.log_likelihood());
        assert_eq!(lw, lw2);
        assert_eq!(*ps.get(a).unwrap(), post);
        assert_eq!(ps.get(a), vs.get(b));
        // errors leave the map unchanged
        let before = *ps.get(a).unwrap();
        assert!(
            fastslam1::landmark_update(
                &mut ps,
                a,
                &m,
                &Vector2::new(f64::NAN, 0.0),
                UpdateForm::Joseph
            )
            .is_err()
        );
        assert!(
            fastslam1::landmark_update(&mut ps, LandmarkId(5), &m, &z1, UpdateForm::Joseph)
                .is_err()
        );
        assert!(fastslam1::landmark_init(&mut ps, &m, &Vector2::new(f64::INFINITY, 0.0)).is_err());
        assert_eq!(ps.len(), 1);
        assert_eq!(*ps.get(a).unwrap(), before);
    }
}

#[cfg(test)]
mod fastslam2_tests {
    use super::{fastslam1, fastslam2};
    use crate::store::VecStore;
    use crate::{RangeBearing, UpdateForm};
    use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
    use proptest::prelude::*;
    use quarry_core::{Gaussian, LandmarkStore, Pose2};

    fn spd3(a: [f64; 6], s: f64) -> Matrix3<f64> {
        let l = Matrix3::new(
            a[0].abs() + 0.01,
            0.0,
            0.0,
            a[1],
            a[2].abs() + 0.01,
            0.0,
            a[3],
            a[4],
            a[5].abs() + 0.01,
        );
        l * l.transpose() * s
    }

    #[test]
    fn a_pose_that_did_not_move_gets_fastslam1s_factor() {
        let lm = Gaussian::try_new(Vector2::new(3.0, 2.0), Matrix2::new(0.04, 0.01, 0.01, 0.05))
            .unwrap();
        let r = Matrix2::new(0.01, 0.0, 0.0, 0.0004);
        let z = Vector2::new(3.5, 0.7);
        let pose = Vector3::new(0.2, -0.1, 0.1);
        let u = fastslam2::pose_update(&pose, &Matrix3::zeros(), &lm, &z, &r).unwrap();
        let (m, p, lw2) = (u.mean, u.cov, u.log_likelihood);
        assert_eq!(m, pose);
        assert!(p.norm() < 1e-15);
        let mut store: VecStore<Gaussian<2>> = VecStore::new();
        let id = store.push(lm);
        let sensor = RangeBearing::with_cov(Pose2::new(pose.x, pose.y, pose.z), r).unwrap();
        let lw1 =
            fastslam1::landmark_update(&mut store, id, &sensor, &z, UpdateForm::Joseph).unwrap();
        assert!((lw1 - lw2).abs() < 1e-9, "{lw1} {lw2}");
    }

    #[test]
    fn the_proposal_moves_the_pose_toward_the_measurement_and_samples_around_it() {
        let lm = Gaussian::try_new(Vector2::new(5.0, 0.0), Matrix2::identity() * 1e-6).unwrap();
        let r = Matrix2::new(1e-4, 0.0, 0.0, 1e-6);
        let p0 = Matrix3::from_diagonal(&Vector3::new(0.25, 0.25, 0.01));
        let u = fastslam2::pose_update(&Vector3::zeros(), &p0, &lm, &Vector2::new(4.7, 0.0), &r)
            .unwrap();
        let (m, p) = (u.mean, u.cov);
        assert!((m.x - 0.3).abs() < 0.01, "{m}");
        assert!(
            p[(0, 0)] < 0.001 && p[(1, 1)] > 0.01,
            "range fixes x, not y: {p}"
        );
        let mut rng = quarry_core::rng::seeded(3);
        let n = 4000;
        let mut mean = Vector3::zeros();
        for _ in 0..n {
            mean += fastslam2::sample_pose(&m, &p, &mut rng);
        }
        mean /= f64::from(n);
        assert!((mean - m).norm() < 0.02, "{mean} vs {m}");
        assert_eq!(fastslam2::sample_pose(&m, &Matrix3::zeros(), &mut rng), m);
        assert!(
            fastslam2::pose_update(
                &Vector3::zeros(),
                &p0,
                &lm,
                &Vector2::new(f64::NAN, 0.0),
                &r
            )
            .is_err()
        );
    }

    proptest! {
        #[test]
        fn posterior_is_spd_and_no_larger(
            a in prop::array::uniform6(-1.0f64..1.0),
            s in 0.001f64..1.0,
            lx in -10.0f64..10.0, ly in -10.0f64..10.0,
            zr in 0.5f64..12.0, zb in -3.0f64..3.0,
            th in -3.1f64..3.1,
        ) {
            prop_assume!(lx.hypot(ly) > 0.5);
            let p0 = spd3(a, s);
            let lm = Gaussian::try_new(Vector2::new(lx, ly), Matrix2::identity() * 0.01).unwrap();
            let r = Matrix2::new(0.01, 0.0, 0.0, 0.001);
            let u = fastslam2::pose_update(
                &Vector3::new(0.0, 0.0, th), &p0, &lm, &Vector2::new(zr, zb), &r,
            ).unwrap();
            let (m, p, lw) = (u.mean, u.cov, u.log_likelihood);
            prop_assert!((u.log_likelihood_at(u.nis) - lw).abs() < 1e-12);
            prop_assert!(lw.is_finite() && m.iter().all(|v| v.is_finite()));
            prop_assert!(m.z.abs() <= std::f64::consts::PI + 1e-12);
            prop_assert!((p - p.transpose()).norm() <= 1e-12 * (1.0 + p.norm()));
            let e = p.symmetric_eigen().eigenvalues;
            prop_assert!(e.iter().all(|v| *v >= -1e-12 * (1.0 + p.norm())), "{e}");
            // conditioning never adds uncertainty: P0 - P is PSD
            let d = (p0 - p).symmetric_eigen().eigenvalues;
            prop_assert!(d.iter().all(|v| *v >= -1e-9 * (1.0 + p0.norm())), "{d}");
        }
    }
}
