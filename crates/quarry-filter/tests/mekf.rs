//! Spec 001 §6.1 tests 8 and 9 for the MEKF (`Ekf<5, 3, EgoCvModel, Position3>`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use proptest::prelude::*;
use quarry_core::{Gaussian, Point2, Pose2};
use quarry_filter::{EgoCvModel, EgoModel, Ekf, OdomNoise, Position3};

type V5 = SVector<f64, 5>;
type M5 = SMatrix<f64, 5, 5>;

/// blockdiag(R(θ), 1, R(θ)) for the [x, y, z, vx, vy] layout.
fn frame_rotation(theta: f64) -> M5 {
    let (s, c) = theta.sin_cos();
    let mut j = M5::zeros();
    j[(0, 0)] = c;
    j[(0, 1)] = -s;
    j[(1, 0)] = s;
    j[(1, 1)] = c;
    j[(2, 2)] = 1.0;
    j[(3, 3)] = c;
    j[(3, 4)] = -s;
    j[(4, 3)] = s;
    j[(4, 4)] = c;
    j
}

fn to_world(pose: &Pose2, g: &Gaussian<5>) -> Gaussian<5> {
    let j = frame_rotation(pose.theta);
    let mut m = j * g.mean;
    m[0] += pose.x;
    m[1] += pose.y;
    Gaussian::new_unchecked(m, j * g.cov * j.transpose())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Equivariance: the MEKF in the robot frame, fed robot-frame measurements, equals a plain
    /// constant-velocity KF in the odometry frame fed the same measurements mapped into that
    /// frame (isotropic Q and R, exact odometry): means within 1e-9, covariances within 1e-9
    /// relative.
    #[test]
    fn mekf_is_equivariant(
        steps in proptest::collection::vec(
            ((-0.2..0.3f64, -0.1..0.1f64, -0.4..0.4f64), (-3.0..3.0f64, -3.0..3.0f64, 0.5..2.0f64), 0.02..0.2f64),
            1..40),
        y0 in (1.0..5.0f64, -2.0..2.0f64, 0.5..1.8f64),
    ) {
        let sigma_p = 0.1;
        let ego = EgoCvModel::new(0.8, 0.05).unwrap();
        let meas = Position3::isotropic(sigma_p).unwrap();
        let p0 = M5::from_diagonal(&V5::from_column_slice(&[0.01, 0.01, 0.01, 1.0, 1.0]));
        let y0 = Vector3::new(y0.0, y0.1, y0.2);
        let init = Gaussian::try_new(V5::new(y0.x, y0.y, y0.z, 0.0, 0.0), p0).unwrap();
        let mut mekf = Ekf::new(init, ego, meas).unwrap();
        // The odometry frame is the robot's start pose: same initial state.
        let mut world = Ekf::new(init, ego, meas).unwrap();
        let mut pose = Pose2::identity();
        for ((dx, dy, dth), (zx, zy, zz), dt) in steps {
            let d = Pose2::new(dx, dy, dth);
            pose = pose.compose(&d);
            mekf.predict(&d, dt).unwrap();
            world.predict(&Pose2::identity(), dt).unwrap();
            let z_r = Vector3::new(zx, zy, zz);
            let pw = pose.apply(&Point2::new(zx, zy));
            mekf.update(&z_r).unwrap();
            world.update(&Vector3::new(pw.x, pw.y, zz)).unwrap();
            let mapped = to_world(&pose, mekf.state());
            let w = world.state();
            prop_assert!((mapped.mean - w.mean).amax() < 1e-9, "{} vs {}", mapped.mean, w.mean);
            prop_assert!((mapped.cov - w.cov).amax() <= 1e-9 * w.cov.amax());
        }
    }

    /// Random sequences of up to 200 predict/update steps with random controls, dt in
    /// [0.01, 0.2], missing measurements, odometry noise and both variants: P stays symmetric
    /// (‖P − Pᵀ‖ ≤ 1e-12‖P‖), Cholesky succeeds, NIS ≥ 0.
    #[test]
    fn mekf_covariance_stays_spd(
        steps in proptest::collection::vec(
            ((-0.5..0.5f64, -1.0..1.0f64), (-0.5..0.5f64, -0.5..0.5f64, -0.2..0.2f64), 0.01..0.2f64, any::<bool>()),
            1..200),
        literal in any::<bool>(),
    ) {
        let variant = if literal { EgoModel::PaperLiteral } else { EgoModel::Compensated };
        let mut ego = EgoCvModel::new(0.5, 0.02).unwrap().with_variant(variant);
        let meas = Position3::new(Matrix3::new(0.02, 0.005, 0.0, 0.005, 0.03, 0.001, 0.0, 0.001, 0.01)).unwrap();
        let init = Gaussian::try_new(V5::new(2.0, 0.5, 1.0, 0.0, 0.0), M5::identity() * 0.1).unwrap();
        let mut f = Ekf::new(init, ego, meas).unwrap();
        for ((v, w), (ex, ey, ez), dt, missing) in steps {
            let d = Pose2::from_unicycle(v, w, dt);
            ego.odom_noise = Some(OdomNoise::from_velocity(v, w, dt, 0.05, 0.02));
            *f.motion_mut() = ego;
            f.predict(&d, dt).unwrap();
            if !missing {
                let z = f.mean().fixed_rows::<3>(0) + Vector3::new(ex, ey, ez);
                let inn = f.update(&z).unwrap();
                prop_assert!(inn.nis >= 0.0);
            }
            let p = f.cov();
            prop_assert!((p - p.transpose()).amax() <= 1e-12 * p.amax());
            prop_assert!(f.state().cholesky().is_ok());
        }
    }
}
