//! Drives every quarry-assoc associator (and the assignment solvers) with arbitrary matrices,
//! priors and parameters: errors are fine, panics are not; successful outputs must be
//! well-formed (finite β in [0, 1], rows summing to 1).
#![no_main]

use libfuzzer_sys::fuzz_target;
use nalgebra::DMatrix;
use quarry_assoc::assign::{hungarian, murty_k_best};
use quarry_assoc::{Gnn, Jipda, Jpda, Method, PaperLikelihood, Pda, Solver};
use quarry_core::{Associator, LikelihoodMatrix, TrackPrior};

struct Bytes<'a>(&'a [u8]);
impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((b, rest)) => {
                self.0 = rest;
                *b
            }
            None => 0,
        }
    }
    fn f64(&mut self) -> f64 {
        let mut b = [0u8; 8];
        for x in &mut b {
            *x = self.u8();
        }
        // Mix raw bit patterns (NaN, inf, subnormals) with tame values.
        match b[0] % 4 {
            0 => f64::from_le_bytes(b),
            1 => f64::NEG_INFINITY,
            _ => -(f64::from(u16::from_le_bytes([b[1], b[2]])) / 1000.0),
        }
    }
    fn prob(&mut self) -> f64 {
        match self.u8() % 8 {
            0 => f64::NAN,
            1 => 0.0,
            2 => 1.0,
            3 => 1.5,
            _ => f64::from(self.u8()) / 255.0,
        }
    }
}

fn check(a: &quarry_core::Association, n: usize, m: usize) {
    assert_eq!(a.beta.shape(), (n, m + 1));
    for i in 0..n {
        let s: f64 = a.beta.row(i).sum();
        assert!((s - 1.0).abs() < 1e-6, "row {i} sums to {s}");
        assert!(
            a.beta
                .row(i)
                .iter()
                .all(|b| b.is_finite() && *b >= -1e-12 && *b <= 1.0 + 1e-9)
        );
    }
    assert!(!a.log_normaliser.is_nan());
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let n = (b.u8() % 9) as usize;
    let m = (b.u8() % 10) as usize;
    let vals: Vec<f64> = (0..n * m).map(|_| b.f64()).collect();
    let raw = DMatrix::from_row_slice(n, m, &vals);
    let _ = hungarian(&raw.map(|v| -v));
    let _ = murty_k_best(&raw.map(|v| -v), (b.u8() % 6) as usize);
    let Ok(lik) = LikelihoodMatrix::new(raw) else {
        return;
    };
    let priors: Vec<TrackPrior> = (0..n)
        .map(|_| TrackPrior {
            existence: if b.u8() % 2 == 0 {
                None
            } else {
                Some(b.prob())
            },
            detection: if b.u8() % 2 == 0 {
                None
            } else {
                Some(b.prob())
            },
        })
        .collect();
    let (pd, pg, kappa) = (b.prob(), b.prob(), b.f64().abs());
    let method = match b.u8() % 4 {
        0 => Method::Auto,
        1 => Method::Exact,
        2 => Method::KBest {
            k: (b.u8() % 20) as usize,
        },
        _ => Method::Lbp,
    };
    let solver = Solver {
        method,
        max_states: 1 + b.u8() as usize * 64,
        ..Solver::default()
    };
    let pri = if b.u8() % 8 == 0 {
        &priors[..n.saturating_sub(1)]
    } else {
        &priors[..]
    };
    if let Ok(j) = Jpda::new(pd, pg, kappa) {
        if let Ok(a) = j.with_solver(solver).associate(&lik, pri) {
            check(&a, n, m);
        }
    }
    if let Ok(j) = Jipda::new(pd, pg, kappa) {
        if let Ok(a) = j
            .with_survival(b.prob())
            .with_solver(solver)
            .associate(&lik, pri)
        {
            check(&a, n, m);
            assert!(a.existence.unwrap().iter().all(|e| (0.0..=1.0).contains(e)));
        }
    }
    if let Ok(a) = (Pda {
        pd,
        prob_gate: pg,
        clutter_density: kappa,
    })
    .associate(&lik, pri)
    {
        check(&a, n, m);
    }
    if let Ok(g) = Gnn::new(pd, pg, kappa) {
        if let Ok(a) = g.associate(&lik, pri) {
            check(&a, n, m);
        }
    }
    if let Ok(a) = PaperLikelihood.associate(&lik, pri) {
        check(&a, n, m);
    }
});
