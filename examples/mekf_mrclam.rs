//! The MEKF (ego-motion compensated EKF, spec 001 §2.9) on real data: in UTIAS MRCLAM dataset 6
//! robot 1 drives on its odometry and observes robot 2 by range and bearing. Robot 2 is tracked in
//! robot 1's frame by the MEKF (odometry as the control) and by a plain EKF that ignores the
//! ego-motion (Δ ≡ 0, the `no_ego` ablation); both are scored against Vicon.
//!
//! `cargo run --release --example mekf_mrclam -- [../shared/data/mrclam-6] [observer] [target slot]`

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use quarry::core::{Gaussian, Pose2};
use quarry::data::mrclam::load;
use quarry::filter::{EgoCvModel, Ekf, Position3};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "../shared/data/mrclam-6".into()),
    );
    let robot: u32 = args.next().map_or(Ok(1), |s| s.parse())?;
    let slot: usize = args.next().map_or(Ok(0), |s| s.parse())?;
    let run = load(&dir, robot)?;
    let (sigma_w, sigma_p) = (0.3, 0.15); // robots drive ≤ 0.3 m/s; range-bearing noise ~0.1-0.2 m
    for ego in [true, false] {
        let mut ekf: Option<Ekf<5, 3, EgoCvModel, Position3>> = None;
        let (mut se, mut n, mut se_pred, mut n_pred) = (0.0, 0usize, 0.0, 0usize);
        for f in &run.frames {
            let (v, w) = f.odometry;
            let d = if ego {
                Pose2::from_unicycle(v, w, f.dt)
            } else {
                Pose2::identity()
            };
            if let Some(e) = ekf.as_mut() {
                e.predict(&d, f.dt)?;
            }
            // truth: the target's Vicon position in the observer's Vicon frame
            let truth = match (f.truth.robot, f.truth.targets.get(slot).copied().flatten()) {
                (Some(p), Some(t)) => Some(p.apply_inverse(&nalgebra::Point2::new(t[0], t[1]))),
                _ => None,
            };
            let obs: Vec<[f64; 2]> = f
                .target_obs
                .iter()
                .zip(&f.truth.target_obs_source)
                .filter(|(_, s)| **s == Some(slot))
                .map(|(z, _)| *z)
                .collect();
            for z in &obs {
                let y = Vector3::new(z[0] * z[1].cos(), z[0] * z[1].sin(), 0.0);
                match ekf.as_mut() {
                    None => {
                        let p0 = SMatrix::<f64, 5, 5>::from_diagonal(
                            &SVector::<f64, 5>::from_column_slice(&[
                                sigma_p * sigma_p,
                                sigma_p * sigma_p,
                                sigma_p * sigma_p,
                                0.25,
                                0.25,
                            ]),
                        );
                        let x0 = SVector::<f64, 5>::from_column_slice(&[y.x, y.y, 0.0, 0.0, 0.0]);
                        ekf = Some(Ekf::new(
                            Gaussian::try_new(x0, p0)?,
                            EgoCvModel::new(sigma_w, 0.01)?,
                            Position3::new(Matrix3::identity() * sigma_p * sigma_p)?,
                        )?);
                    }
                    Some(e) => {
                        if let Some(t) = truth {
                            // prediction error just before the measurement is used
                            se_pred += (e.mean()[0] - t.x).powi(2) + (e.mean()[1] - t.y).powi(2);
                            n_pred += 1;
                        }
                        e.update(&y)?;
                    }
                }
            }
            if let (Some(e), Some(t)) = (ekf.as_ref(), truth) {
                se += (e.mean()[0] - t.x).powi(2) + (e.mean()[1] - t.y).powi(2);
                n += 1;
            }
        }
        #[allow(clippy::cast_precision_loss)]
        let (rmse, rmse_pred) = (
            (se / n.max(1) as f64).sqrt(),
            (se_pred / n_pred.max(1) as f64).sqrt(),
        );
        println!(
            "{{\"filter\": \"{}\", \"observer\": {robot}, \"target\": {}, \"frames\": {n}, \"updates\": {n_pred}, \"rmse_m\": {rmse:.4}, \"rmse_before_update_m\": {rmse_pred:.4}}}",
            if ego { "mekf" } else { "ekf_no_ego" },
            run.target_robots.get(slot).copied().unwrap_or(0)
        );
    }
    Ok(())
}
