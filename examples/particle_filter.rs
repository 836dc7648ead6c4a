//! A bootstrap particle filter for a ground robot (the unicycle model, noise through the control)
//! with range-bearing fixes to a known beacon: log-domain weights, effective sample size, and
//! systematic resampling when it drops below N/2.
//!
//! `cargo run --example particle_filter`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{Vector2, Vector3};
use quarry::core::{MeasurementModel, Pose2, SampledMotion, rng::seeded};
use quarry::filter::particles::{LogWeights, Systematic, effective_sample_size};
use quarry::filter::{RangeBearing, Unicycle};
use rand::Rng;
use rand_distr::StandardNormal;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n = 500;
    let dt = 0.1;
    let beacon = Vector2::new(5.0, 5.0);
    let (sigma_r, sigma_b) = (0.2, 0.05);
    let robot = Unicycle::new(0.1, 0.05)?;
    let mut rng = seeded(11);

    let mut truth = Vector3::new(0.0, 0.0, 0.0);
    let mut particles: Vec<Vector3<f64>> = (0..n)
        .map(|_| {
            truth
                + Vector3::new(
                    0.3 * rng.sample::<f64, _>(StandardNormal),
                    0.3 * rng.sample::<f64, _>(StandardNormal),
                    0.1 * rng.sample::<f64, _>(StandardNormal),
                )
        })
        .collect();
    let mut log_w = LogWeights::uniform(n)?;
    let mut resamples = 0;

    for k in 0..150 {
        let u = (1.0, 0.3); // speed 1 m/s, turning at 0.3 rad/s
        truth = robot.sample(&truth, &u, dt, &mut rng);
        for p in &mut particles {
            *p = robot.sample(p, &u, dt, &mut rng);
        }

        // Range-bearing to the beacon, measured from the true pose.
        let sensor = |x: &Vector3<f64>| Pose2::new(x[0], x[1], x[2]);
        let m_true = RangeBearing::new(sensor(&truth), sigma_r, sigma_b)?;
        let z = m_true.predict(&beacon)
            + Vector2::new(
                sigma_r * rng.sample::<f64, _>(StandardNormal),
                sigma_b * rng.sample::<f64, _>(StandardNormal),
            );

        // Weight: ln p(z | particle), bearing residual wrapped by the model.
        let lik: Vec<f64> = particles
            .iter()
            .map(|p| {
                let m = RangeBearing::new(sensor(p), sigma_r, sigma_b).unwrap();
                let nu = m.residual(&z, &m.predict(&beacon));
                -0.5 * ((nu[0] / sigma_r).powi(2) + (nu[1] / sigma_b).powi(2))
            })
            .collect();
        log_w.add(&lik)?;
        let w = log_w.normalised()?; // an error if every weight is zero or NaN
        let ess = effective_sample_size(&w);

        if k % 30 == 0 {
            let est: Vector3<f64> = particles.iter().zip(&w).map(|(p, w)| p * *w).sum();
            println!(
                "t = {:4.1} s  ESS = {ess:6.1}  position error {:.3} m",
                k as f64 * dt,
                (est.fixed_rows::<2>(0) - truth.fixed_rows::<2>(0)).norm()
            );
        }
        if ess < n as f64 / 2.0 {
            let mut idx = Vec::new();
            Systematic.resample_into(&w, &mut rng, &mut idx)?;
            particles = idx.iter().map(|&i| particles[i]).collect();
            log_w.reset_uniform();
            resamples += 1;
        } else {
            log_w.normalise()?;
        }
    }
    println!("resampled {resamples} times out of 150 steps");
    Ok(())
}
