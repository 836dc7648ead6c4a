//! Fit the human contour model (an ellipse, spec 003 §2.6) to a partial, noisy arc of laser
//! points with 2-D ICP, as the lidar people tracker does for each cluster.
//!
//! `cargo run --example icp_contour`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::cloud::contour::{EllipseModel, pca_angle};
use quarry::cloud::icp::Icp2d;
use quarry::core::{Point2, Pose2, Registration2, rng::seeded};
use rand_distr::{Distribution, Normal};

fn main() {
    let model = EllipseModel::default();
    let model_pts = model.points().expect("valid model");

    // a person at (4, 3) with the shoulder line at 30 degrees; the scanner sees the near half
    let truth = Pose2::new(4.0, 3.0, 30f64.to_radians());
    let mut rng = seeded(1);
    let noise = Normal::new(0.0, 0.01).unwrap();
    let data: Vec<Point2> = model_pts[36..]
        .iter()
        .map(|m| {
            let p = truth.apply(m);
            Point2::new(p.x + noise.sample(&mut rng), p.y + noise.sample(&mut rng))
        })
        .collect();

    // new-cluster start (spec §2.6): the centroid and the two PCA orientations; keep the better
    let c = data
        .iter()
        .fold(Point2::origin(), |a, p| Point2::new(a.x + p.x, a.y + p.y));
    let c = Point2::new(c.x / data.len() as f64, c.y / data.len() as f64);
    let phi = pca_angle(&data).expect("enough points");
    let icp = Icp2d::contour();
    let best = [phi, phi + std::f64::consts::FRAC_PI_2]
        .iter()
        .map(|&a| {
            icp.register(&model_pts, &data, Pose2::new(c.x, c.y, a))
                .expect("valid input")
        })
        .min_by(|a, b| a.rms.total_cmp(&b.rms))
        .expect("two starts");

    println!(
        "fitted centre ({:.3}, {:.3}), orientation {:.1} deg (mod 180), RMS {:.4} m, {} inliers, {} iterations",
        best.pose.x,
        best.pose.y,
        best.pose.theta.to_degrees().rem_euclid(180.0),
        best.rms,
        best.inliers,
        best.iters
    );
    println!(
        "truth        ({:.3}, {:.3}), orientation {:.1} deg",
        truth.x,
        truth.y,
        truth.theta.to_degrees()
    );
    let err = (best.pose.x - truth.x).hypot(best.pose.y - truth.y);
    println!("centre error {:.1} cm", err * 100.0);
}
