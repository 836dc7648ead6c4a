//! MeanShift clustering of 2-D points (spec 003 §2.5): three synthetic "people" seen by a laser,
//! clustered with the paper's flat kernel (h = 0.30 m), deterministic whatever the point order.
//!
//! `cargo run --example meanshift`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::cloud::cluster::MeanShift;
use quarry::core::{Clusterer, Point2, rng::seeded};
use rand_distr::{Distribution, Normal};

fn main() {
    let mut rng = seeded(7);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let centres = [
        Point2::new(1.0, 2.0),
        Point2::new(3.0, 2.5),
        Point2::new(2.0, 4.0),
    ];
    let mut pts = Vec::new();
    for c in &centres {
        for _ in 0..40 {
            pts.push(Point2::new(
                c.x + noise.sample(&mut rng),
                c.y + noise.sample(&mut rng),
            ));
        }
    }
    // one stray point far from everyone: labelled noise
    pts.push(Point2::new(9.0, 9.0));

    let clustering = MeanShift::default().cluster(&pts).expect("finite points");
    println!("{} clusters", clustering.modes.len());
    for (k, (m, n)) in clustering.modes.iter().zip(&clustering.sizes).enumerate() {
        println!("  cluster {k}: mode ({:.3}, {:.3}), {n} points", m.x, m.y);
    }
    let noise_pts = clustering.labels.iter().filter(|l| l.is_none()).count();
    println!("{noise_pts} noise point(s)");
}
