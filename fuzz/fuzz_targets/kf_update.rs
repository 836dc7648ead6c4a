//! Drives the linear KF (CV model + position measurement) with arbitrary, possibly non-finite
//! numbers: priors, noise, time steps and measurements. It must never panic; errors are fine.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nalgebra::{Matrix2, Matrix4, Vector2, Vector4};
use quarry_core::Gaussian;
use quarry_filter::{ConstantVelocity2, CvNoise, Ekf, Position2, UpdateForm, ekf};

#[path = "common/floats.rs"]
mod common_floats;
use common_floats::floats;

fuzz_target!(|data: &[u8]| {
    let mut it = floats(data).chain(std::iter::repeat(0.5));
    let mut next = || it.next().unwrap_or(0.0);
    let mean = Vector4::from_fn(|_, _| next());
    let cov = Matrix4::from_fn(|_, _| next());
    let r = Matrix2::from_fn(|_, _| next());
    let noise = if next() > 0.0 {
        CvNoise::Cwna { q: next() }
    } else {
        CvNoise::Dwna { sigma_a: next() }
    };
    let cv = ConstantVelocity2 { noise };
    let pos = Position2 { r };
    let prior = Gaussian::new_unchecked(mean, cov);
    for form in [
        UpdateForm::Joseph,
        UpdateForm::Standard,
        UpdateForm::Symmetrised,
    ] {
        let z = Vector2::new(next(), next());
        let dt = next();
        if let Ok(p) = ekf::predict(&prior, &cv, &(), dt) {
            let _ = ekf::update(&p, &pos, &z, form);
        }
        let _ = ekf::update(&prior, &pos, &z, form);
    }
    // The wrapper: a failed step leaves the state unchanged.
    if let (Ok(pos), Ok(cv)) = (Position2::new(r), ConstantVelocity2::new(noise)) {
        if let Ok(mut kf) = Ekf::new(prior, cv, pos) {
            for _ in 0..8 {
                let before = *kf.state();
                let dt = next();
                if kf.predict(&(), dt).is_err() {
                    assert_eq!(*kf.state(), before);
                }
                let before = *kf.state();
                let z = Vector2::new(next(), next());
                if kf.update(&z).is_err() {
                    assert_eq!(*kf.state(), before);
                } else {
                    assert!(kf.mean().iter().all(|v| v.is_finite()));
                }
            }
        }
    }
});
