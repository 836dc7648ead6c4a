//! Drives the EKF with range-bearing measurements (point and CV states), the PDA update and the
//! range-bearing inverse model with arbitrary, possibly non-finite numbers. It must never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nalgebra::{Matrix2, Matrix4, Vector2, Vector4};
use quarry_core::{Gaussian, InverseMeasurement, Pose2};
use quarry_filter::{
    ConstantVelocity2, CvNoise, Ekf, RangeBearing, RangeBearingCv, UpdateForm, ekf, pda,
};

#[path = "common/floats.rs"]
mod common_floats;
use common_floats::floats;

fuzz_target!(|data: &[u8]| {
    let mut it = floats(data).chain(std::iter::repeat(0.25));
    let mut next = || it.next().unwrap_or(0.0);
    let sensor = Pose2 {
        x: next(),
        y: next(),
        theta: next(),
    };
    let r = Matrix2::from_fn(|_, _| next());
    let point = RangeBearing { sensor, r };
    let cvm = RangeBearingCv { point };
    let g2 = Gaussian::new_unchecked(
        Vector2::new(next(), next()),
        Matrix2::from_fn(|_, _| next()),
    );
    let g4 = Gaussian::new_unchecked(
        Vector4::from_fn(|_, _| next()),
        Matrix4::from_fn(|_, _| next()),
    );
    let z = Vector2::new(next(), next());
    for form in [
        UpdateForm::Joseph,
        UpdateForm::Standard,
        UpdateForm::Symmetrised,
    ] {
        let _ = ekf::update(&g2, &point, &z, form);
        let _ = ekf::update(&g4, &cvm, &z, form);
    }
    let _ = point.initialise(&z);
    let _ = cvm.initialise_with_velocity(&z, next());
    let zs = [z, Vector2::new(next(), next())];
    let beta = [next(), next(), next()];
    let _ = pda::update_with_model(&g4, &cvm, &zs, &beta);
    let cv = ConstantVelocity2 {
        noise: CvNoise::Cwna { q: next() },
    };
    if let Ok(mut f) = Ekf::new(g4, cv, cvm) {
        for _ in 0..8 {
            let before = *f.state();
            if f.predict(&(), next()).is_err() {
                assert_eq!(*f.state(), before);
            }
            let before = *f.state();
            if f.update(&Vector2::new(next(), next())).is_err() {
                assert_eq!(*f.state(), before);
            }
        }
    }
});
