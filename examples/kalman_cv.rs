//! A constant-velocity Kalman filter tracking a simulated target from noisy position fixes.
//!
//! `cargo run --example kalman_cv`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{Matrix4, Vector2, Vector4};
use quarry::core::{Gaussian, rng::seeded};
use quarry::filter::{ConstantVelocity2, Ekf, Position2};
use rand::Rng;
use rand_distr::StandardNormal;

fn main() -> Result<(), quarry::filter::FilterError> {
    let dt = 0.1;
    let sigma = 0.5; // measurement noise, m
    // State [x, y, vx, vy]; continuous white-noise acceleration q = 0.05 m²/s³ (a gently
    // manoeuvring target).
    let x0 = Gaussian::try_new(Vector4::zeros(), Matrix4::identity() * 10.0)?;
    let mut kf = Ekf::new(
        x0,
        ConstantVelocity2::cwna(0.05)?,
        Position2::isotropic(sigma)?,
    )?;

    let mut rng = seeded(7);
    let mut truth = Vector4::new(0.0, 0.0, 1.0, 0.5);
    let (mut se_filter, mut se_raw) = (0.0, 0.0);
    let steps = 200;
    for _ in 0..steps {
        truth += Vector4::new(truth[2] * dt, truth[3] * dt, 0.0, 0.0);
        let noise = Vector2::new(
            rng.sample::<f64, _>(StandardNormal),
            rng.sample::<f64, _>(StandardNormal),
        );
        let z = truth.fixed_rows::<2>(0) + noise * sigma;

        kf.predict(&(), dt)?;
        let innovation = kf.update(&z)?; // Joseph-form update; nis, log-likelihood for gating
        assert!(innovation.nis >= 0.0);

        se_filter += (kf.mean().fixed_rows::<2>(0) - truth.fixed_rows::<2>(0)).norm_squared();
        se_raw += (z - truth.fixed_rows::<2>(0)).norm_squared();
    }
    println!(
        "position RMSE: filter {:.3} m, raw measurements {:.3} m",
        (se_filter / f64::from(steps)).sqrt(),
        (se_raw / f64::from(steps)).sqrt()
    );
    println!(
        "final velocity estimate ({:.2}, {:.2}) m/s (truth (1.00, 0.50))",
        kf.mean()[2],
        kf.mean()[3]
    );
    Ok(())
}
