//! Rao-Blackwellized particle-filter kernels.
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
