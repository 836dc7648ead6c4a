//! JPDA and JIPDA marginal association probabilities for a hand-made likelihood matrix.
//!
//! Run: `cargo run --example jpda_marginals`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::DMatrix;
use quarry::assoc::{Gnn, Jipda, Jpda};
use quarry::core::{Associator, LikelihoodMatrix, TrackPrior};

fn main() {
    // ln g_ij of 3 tracks (rows) against 4 detections (columns); -inf = outside the gate.
    let x = f64::NEG_INFINITY;
    let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(
        3,
        4,
        &[
            -1.2, -2.0, x, x, //
            -3.0, -1.1, -2.5, x, //
            x, x, -1.8, -6.0,
        ],
    ))
    .expect("finite or -inf log-likelihoods");
    // P_D = 0.9, P_G = 0.99, clutter density 0.01 per unit area.
    let jpda = Jpda::new(0.9, 0.99, 0.01).unwrap();
    let a = jpda.associate(&lik, &[TrackPrior::default(); 3]).unwrap();
    println!("JPDA beta (column 0 = missed):{}", a.beta);
    println!("ln c = {:.6}", a.log_normaliser);

    let prior = [
        TrackPrior {
            existence: Some(0.9),
            detection: None,
        },
        TrackPrior {
            existence: Some(0.5),
            detection: None,
        },
        TrackPrior {
            existence: Some(0.2),
            detection: Some(0.6),
        },
    ];
    let b = Jipda::new(0.9, 0.99, 0.01)
        .unwrap()
        .associate(&lik, &prior)
        .unwrap();
    println!("JIPDA beta (conditioned on existence):{}", b.beta);
    println!("posterior existence: {:?}", b.existence.unwrap());

    let g = Gnn::new(0.9, 0.99, 0.01)
        .unwrap()
        .associate(&lik, &[TrackPrior::default(); 3])
        .unwrap();
    println!("GNN assignment: {:?}", g.assignment.unwrap());
}
