#![allow(clippy::unwrap_used, clippy::expect_used, clippy::needless_range_loop)]
//! Property tests: exact marginals against brute-force enumeration, invariants, limits.

use nalgebra::DMatrix;
use proptest::prelude::*;
use quarry_assoc::{Gnn, Jipda, Jpda, Method, PaperLikelihood, Pda, Solver};
use quarry_core::{Associator, LikelihoodMatrix, TrackPrior};
use quarry_testkit::brute;
use quarry_testkit::strategies::gated_log_likelihoods;

const NI: f64 = f64::NEG_INFINITY;

/// The JPDA score matrix for given log-likelihoods.
fn scores(lik: &DMatrix<f64>, pd: &[f64], pg: f64, kappa: f64, psi: &[f64]) -> DMatrix<f64> {
    let (n, m) = lik.shape();
    DMatrix::from_fn(n, m + 1, |i, j| {
        if j == 0 {
            1.0 - pd[i] * pg * psi[i]
        } else {
            pd[i] * psi[i] * lik[(i, j - 1)].exp() / kappa
        }
    })
}

prop_compose! {
    /// Random small problem: n ≤ 5 tracks, m ≤ 6 detections, ~60 % of pairs gated.
    fn problem()(n in 1usize..=5, m in 0usize..=6)
        (lik in gated_log_likelihoods(n, m),
         pd in proptest::collection::vec(prop_oneof![4 => 0.3f64..1.0, 1 => Just(1.0), 1 => Just(0.0)], n),
         psi in proptest::collection::vec(0.0f64..=1.0, n),
         pg in 0.5f64..=1.0, kappa in 1e-4f64..1.0)
        -> (DMatrix<f64>, Vec<f64>, Vec<f64>, f64, f64) {
        (lik, pd, psi, pg, kappa)
    }
}

fn priors(pd: &[f64], psi: Option<&[f64]>) -> Vec<TrackPrior> {
    pd.iter()
        .enumerate()
        .map(|(i, &d)| TrackPrior {
            existence: psi.map(|p| p[i]),
            detection: Some(d),
        })
        .collect()
}

fn exact_solver() -> Solver {
    Solver {
        method: Method::Exact,
        ..Solver::default()
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(160))]

    #[test]
    fn jpda_exact_equals_brute_force((lik, pd, _psi, pg, kappa) in problem()) {
        let n = lik.nrows();
        let l = scores(&lik, &pd, pg, kappa, &vec![1.0; n]);
        let (bb, c) = brute::jpda_marginals(&l);
        let jpda = Jpda::new(0.5, pg, kappa).unwrap().with_solver(exact_solver());
        let a = jpda.associate(&LikelihoodMatrix::new(lik.clone()).unwrap(), &priors(&pd, None)).unwrap();
        if c > 0.0 {
            prop_assert!((a.beta.clone() - bb).abs().max() < 1e-9, "{} vs brute", a.beta);
            prop_assert!((a.log_normaliser - c.ln()).abs() < 1e-10 * c.ln().abs().max(1.0));
        } else {
            prop_assert_eq!(a.log_normaliser, NI);
        }
        // Invariants (spec 000 §6.1 test 9).
        for i in 0..n {
            prop_assert!((a.beta.row(i).sum() - 1.0).abs() < 1e-12);
            for j in 0..lik.ncols() {
                prop_assert!(a.beta[(i, j + 1)] >= 0.0 && a.beta[(i, j + 1)] <= 1.0 + 1e-12);
                if lik[(i, j)] == NI { prop_assert_eq!(a.beta[(i, j + 1)], 0.0); }
            }
        }
        for j in 0..lik.ncols() {
            prop_assert!(a.beta.column(j + 1).sum() <= 1.0 + 1e-12);
        }
        // Auto (exact here) and k-best with every event agree with exact.
        let auto = Jpda::new(0.5, pg, kappa).unwrap()
            .associate(&LikelihoodMatrix::new(lik.clone()).unwrap(), &priors(&pd, None)).unwrap();
        prop_assert!((auto.beta.clone() - a.beta.clone()).abs().max() < 1e-12);
        if c > 0.0 && lik.nrows() * lik.ncols() <= 16 {
            let kb = Jpda::new(0.5, pg, kappa).unwrap()
                .with_solver(Solver { method: Method::KBest { k: 100_000 }, ..Solver::default() })
                .associate(&LikelihoodMatrix::new(lik.clone()).unwrap(), &priors(&pd, None)).unwrap();
            prop_assert!((kb.beta - a.beta).abs().max() < 1e-9);
            prop_assert!((kb.log_normaliser - c.ln()).abs() < 1e-9 * c.ln().abs().max(1.0));
        }
    }

    #[test]
    fn jipda_exact_equals_brute_force((lik, pd, psi, pg, kappa) in problem()) {
        let n = lik.nrows();
        let l = scores(&lik, &pd, pg, kappa, &psi);
        let (bt, c) = brute::jpda_marginals(&l);
        prop_assume!(c > 0.0);
        let jipda = Jipda::new(0.5, pg, kappa).unwrap().with_solver(exact_solver());
        let a = jipda.associate(&LikelihoodMatrix::new(lik.clone()).unwrap(), &priors(&pd, Some(&psi))).unwrap();
        let ex = a.existence.clone().unwrap();
        for i in 0..n {
            let dpg = pd[i] * pg;
            let r = if 1.0 - dpg * psi[i] > 0.0 { (1.0 - dpg) * psi[i] / (1.0 - dpg * psi[i]) } else { 0.0 };
            let det: f64 = bt.row(i).iter().skip(1).sum();
            let post = bt[(i, 0)] * r + det;
            prop_assert!((ex[i] - post).abs() < 1e-9);
            prop_assert!((0.0..=1.0).contains(&ex[i]));
            prop_assert!((a.beta.row(i).sum() - 1.0).abs() < 1e-12);
            if post > 1e-6 {
                for j in 1..=lik.ncols() {
                    prop_assert!((a.beta[(i, j)] - bt[(i, j)] / post).abs() < 1e-8);
                }
            }
        }
        prop_assert!((a.log_normaliser - c.ln()).abs() < 1e-10 * c.ln().abs().max(1.0));
    }

    #[test]
    fn permutation_invariance((lik, pd, _psi, pg, kappa) in problem(), seed in any::<u64>()) {
        let (n, m) = lik.shape();
        // Deterministic permutations from the seed.
        let mut pr: Vec<usize> = (0..n).collect();
        let mut pc: Vec<usize> = (0..m).collect();
        let mut s = seed | 1;
        for v in [&mut pr, &mut pc] {
            for k in (1..v.len()).rev() {
                s ^= s << 13; s ^= s >> 7; s ^= s << 17;
                v.swap(k, (s % (k as u64 + 1)) as usize);
            }
        }
        let lik2 = DMatrix::from_fn(n, m, |i, j| lik[(pr[i], pc[j])]);
        let pd2: Vec<f64> = pr.iter().map(|&i| pd[i]).collect();
        let jpda = Jpda::new(0.5, pg, kappa).unwrap();
        let a = jpda.associate(&LikelihoodMatrix::new(lik).unwrap(), &priors(&pd, None)).unwrap();
        let b = jpda.associate(&LikelihoodMatrix::new(lik2).unwrap(), &priors(&pd2, None)).unwrap();
        for i in 0..n {
            prop_assert!((a.beta[(pr[i], 0)] - b.beta[(i, 0)]).abs() < 1e-12);
            for j in 0..m {
                prop_assert!((a.beta[(pr[i], pc[j] + 1)] - b.beta[(i, j + 1)]).abs() < 1e-12);
            }
        }
        if a.log_normaliser.is_finite() {
            prop_assert!((a.log_normaliser - b.log_normaliser).abs() < 1e-10 * a.log_normaliser.abs().max(1.0));
        }
    }

    #[test]
    fn gnn_equals_brute_force_optimum((lik, pd, _psi, pg, kappa) in problem()) {
        let n = lik.nrows();
        let l = scores(&lik, &pd, pg, kappa, &vec![1.0; n]);
        // Best event by brute force.
        let best = brute::best_event_log_weight(&l);
        let g = Gnn::new(0.5, pg, kappa).unwrap();
        let a = g.associate(&LikelihoodMatrix::new(lik).unwrap(), &priors(&pd, None)).unwrap();
        if best.is_finite() {
            prop_assert!((a.log_normaliser - best).abs() < 1e-9 * best.abs().max(1.0), "{} vs {}", a.log_normaliser, best);
        } else {
            prop_assert_eq!(a.log_normaliser, NI);
        }
        let asg = a.assignment.unwrap();
        let mut seen = std::collections::HashSet::new();
        for c in asg.iter().flatten() { prop_assert!(seen.insert(*c)); }
    }

    #[test]
    fn lbp_within_tolerance_of_exact(n in 2usize..=7, extra in 0usize..=2,
                                     vals in proptest::collection::vec(-6.0f64..0.0, 81),
                                     pd in 0.5f64..0.99, kappa in 1e-3f64..0.5) {
        // Dense, mutually gated clusters: the hardest case for LBP.
        let m = n + extra;
        let lik = DMatrix::from_fn(n, m, |i, j| vals[i * 9 + j]);
        let lm = LikelihoodMatrix::new(lik).unwrap();
        let pri = vec![TrackPrior::default(); n];
        let ex = Jpda::new(pd, 0.99, kappa).unwrap().with_solver(exact_solver()).associate(&lm, &pri).unwrap();
        let lb = Jpda::new(pd, 0.99, kappa).unwrap()
            .with_solver(Solver { method: Method::Lbp, ..Solver::default() })
            .associate(&lm, &pri).unwrap();
        let diff = (ex.beta.clone() - lb.beta.clone()).abs();
        let err = diff.max();
        let mean = diff.sum() / (n * (m + 1)) as f64;
        // Documented tolerance (engine docs): worst entry ≤ 0.35, mean ≤ 0.2 on dense clusters (5000-case run).
        prop_assert!(err <= 0.35, "LBP error {err}");
        prop_assert!(mean <= 0.2, "LBP mean error {mean}");
        for i in 0..n { prop_assert!((lb.beta.row(i).sum() - 1.0).abs() < 1e-9); }
        // Bethe ln c is a lower bound of the permanent-type sum (Gurvits), within (n+m)/2 ln 2.
        prop_assert!(lb.log_normaliser <= ex.log_normaliser + 1e-9);
        prop_assert!(ex.log_normaliser - lb.log_normaliser <= (n + m) as f64 / 2.0 * 2f64.ln());
    }

    #[test]
    fn lbp_exact_on_chains(n in 2usize..=6, vals in proptest::collection::vec(-6.0f64..0.0, 12), kappa in 1e-3f64..0.5) {
        // Track i gates detections i and i+1: an acyclic gating graph, where BP is exact.
        let m = n + 1;
        let lik = DMatrix::from_fn(n, m, |i, j| if j == i || j == i + 1 { vals[2 * i + (j - i)] } else { NI });
        let lm = LikelihoodMatrix::new(lik).unwrap();
        let pri = vec![TrackPrior::default(); n];
        let ex = Jpda::new(0.9, 0.99, kappa).unwrap().with_solver(exact_solver()).associate(&lm, &pri).unwrap();
        let lb = Jpda::new(0.9, 0.99, kappa).unwrap()
            .with_solver(Solver { method: Method::Lbp, ..Solver::default() })
            .associate(&lm, &pri).unwrap();
        prop_assert!((ex.beta - lb.beta).abs().max() < 1e-8);
        prop_assert!((ex.log_normaliser - lb.log_normaliser).abs() < 1e-8);
    }

    #[test]
    fn pda_is_jpda_for_separated_tracks(vals in proptest::collection::vec(-8.0f64..0.0, 12)) {
        // 3 tracks, each gating its own 2 detections only.
        let lik = DMatrix::from_fn(3, 6, |i, j| if j / 2 == i { vals[i * 2 + j % 2] } else { NI });
        let lm = LikelihoodMatrix::new(lik).unwrap();
        let pri = vec![TrackPrior::default(); 3];
        let a = Jpda::new(0.8, 0.99, 0.01).unwrap().associate(&lm, &pri).unwrap();
        let b = Pda { pd: 0.8, prob_gate: 0.99, clutter_density: 0.01 }.associate(&lm, &pri).unwrap();
        prop_assert!((a.beta - b.beta).abs().max() < 1e-12);
        prop_assert!((a.log_normaliser - b.log_normaliser).abs() < 1e-10);
    }
}

#[test]
fn one_target_full_detection_is_paper_beta() {
    // P_D = 1, P_G = 1: L_0 = 0 and κ cancels ⇒ β_j = g_j / Σ g (spec 000 §6.1 test 12).
    let lik = DMatrix::from_row_slice(1, 3, &[-1.0, -2.5, -0.3]);
    let lm = LikelihoodMatrix::new(lik).unwrap();
    let a = Jpda::new(1.0, 1.0, 0.37)
        .unwrap()
        .associate(&lm, &[TrackPrior::default()])
        .unwrap();
    let p = PaperLikelihood
        .associate(&lm, &[TrackPrior::default()])
        .unwrap();
    assert!((a.beta.clone() - p.beta).abs().max() < 1e-12);
    assert_eq!(a.beta[(0, 0)], 0.0);
}

#[test]
fn jipda_with_certain_existence_is_jpda() {
    let lik = DMatrix::from_row_slice(3, 3, &[-1.0, -2.0, NI, -1.5, -0.5, -3.0, NI, -2.0, -1.0]);
    let lm = LikelihoodMatrix::new(lik).unwrap();
    let pri = vec![
        TrackPrior {
            existence: Some(1.0),
            detection: None
        };
        3
    ];
    let a = Jpda::new(0.9, 0.99, 0.05)
        .unwrap()
        .associate(&lm, &pri)
        .unwrap();
    let b = Jipda::new(0.9, 0.99, 0.05)
        .unwrap()
        .associate(&lm, &pri)
        .unwrap();
    assert!((a.beta - b.beta).abs().max() < 1e-12);
    assert!((a.log_normaliser - b.log_normaliser).abs() < 1e-12);
    assert!(
        b.existence
            .unwrap()
            .iter()
            .all(|&e| (e - 1.0).abs() < 1e-12)
    );
}

#[test]
fn paper_eq11_is_finite_when_likelihoods_underflow() {
    let lik = DMatrix::from_row_slice(2, 2, &[-800.0, -801.0, -802.0, -800.5]);
    let w = quarry_assoc::weights_eq11(&LikelihoodMatrix::new(lik).unwrap());
    assert!(w.is_finite());
    // Closed form per column: LSE(2 ln g) − LSE(ln g).
    let lse = |a: f64, b: f64| a.max(b) + (1.0 + (-(a - b).abs()).exp()).ln();
    let want = (lse(-1600.0, -1604.0) - lse(-800.0, -802.0))
        + (lse(-1602.0, -1601.0) - lse(-801.0, -800.5));
    assert!((w - want).abs() < 1e-9);
}

#[test]
fn underflowing_likelihoods_are_fine() {
    // ln g ≈ −2000: exp underflows, the log-domain engine does not.
    let lik = DMatrix::from_row_slice(2, 2, &[-2000.0, -2001.0, -2000.5, -2000.0]);
    let lm = LikelihoodMatrix::new(lik).unwrap();
    let a = Jpda::new(0.9, 0.99, 1e-3)
        .unwrap()
        .associate(&lm, &[TrackPrior::default(); 2])
        .unwrap();
    assert!(a.log_normaliser.is_finite());
    assert!((a.beta[(0, 0)] - 1.0).abs() < 1e-12); // detections hopeless vs missed
}

#[test]
fn bad_inputs_give_errors_or_defined_results() {
    let lm = LikelihoodMatrix::new(DMatrix::from_row_slice(2, 1, &[-1.0, NI])).unwrap();
    let pri = [TrackPrior::default(); 2];
    // Wrong number of priors.
    assert!(
        Jpda::new(0.9, 0.99, 1e-3)
            .unwrap()
            .associate(&lm, &pri[..1])
            .is_err()
    );
    // Bad parameters.
    assert!(Jpda::new(f64::NAN, 0.99, 1e-3).is_err());
    assert!(Jpda::new(0.9, 0.0, 1e-3).is_err());
    assert!(Jpda::new(0.9, 0.99, 0.0).is_err());
    assert!(
        Jipda::new(0.9, 0.99, 1e-3)
            .unwrap()
            .with_survival(1.5)
            .associate(&lm, &pri)
            .is_err()
    );
    let bad = [
        TrackPrior {
            existence: Some(f64::NAN),
            detection: None,
        },
        TrackPrior::default(),
    ];
    assert!(
        Jipda::new(0.9, 0.99, 1e-3)
            .unwrap()
            .associate(&lm, &bad)
            .is_err()
    );
    // Zero detection probability: nothing is associated.
    let z = [TrackPrior {
        existence: None,
        detection: Some(0.0),
    }; 2];
    let a = Jpda::new(0.9, 0.99, 1e-3)
        .unwrap()
        .associate(&lm, &z)
        .unwrap();
    assert_eq!(a.beta[(0, 0)], 1.0);
    assert_eq!(a.log_normaliser, 0.0);
    // P_D P_G = 1 and an empty gate: impossible event, defined result.
    let a = Jpda::new(1.0, 1.0, 1e-3)
        .unwrap()
        .associate(&lm, &pri)
        .unwrap();
    assert_eq!(a.log_normaliser, NI);
    assert_eq!(a.beta[(1, 0)], 1.0);
    // Empty problems.
    let e = LikelihoodMatrix::new(DMatrix::zeros(0, 3)).unwrap();
    assert_eq!(
        Jpda::new(0.9, 0.99, 1e-3)
            .unwrap()
            .associate(&e, &[])
            .unwrap()
            .beta
            .shape(),
        (0, 4)
    );
    let e = LikelihoodMatrix::new(DMatrix::zeros(2, 0)).unwrap();
    let a = Jpda::new(0.9, 0.99, 1e-3)
        .unwrap()
        .associate(&e, &pri)
        .unwrap();
    assert!((a.log_normaliser - 2.0 * (1.0 - 0.9 * 0.99f64).ln()).abs() < 1e-12);
    // Exact on an oversized cluster is an error, Auto falls back to LBP.
    let big = LikelihoodMatrix::new(DMatrix::from_fn(24, 24, |i, j| -(((i + 2 * j) % 5) as f64)))
        .unwrap();
    let p24 = vec![TrackPrior::default(); 24];
    let small = Solver {
        method: Method::Exact,
        max_states: 1000,
        ..Solver::default()
    };
    assert!(
        Jpda::new(0.9, 0.99, 1e-3)
            .unwrap()
            .with_solver(small)
            .associate(&big, &p24)
            .is_err()
    );
    let a = Jpda::new(0.9, 0.99, 1e-3)
        .unwrap()
        .associate(&big, &p24)
        .unwrap();
    for i in 0..24 {
        assert!((a.beta.row(i).sum() - 1.0).abs() < 1e-9);
    }
}

#[test]
fn twelve_mutually_gated_targets_are_exact() {
    let n = 12;
    let lik = DMatrix::from_fn(n, n, |i, j| {
        -0.5 * ((i as f64 - j as f64) * 0.7).powi(2) - 0.1 * (i * j % 3) as f64
    });
    let lm = LikelihoodMatrix::new(lik).unwrap();
    let pri = vec![TrackPrior::default(); n];
    let ex = Jpda::new(0.9, 0.99, 1e-2)
        .unwrap()
        .with_solver(exact_solver())
        .associate(&lm, &pri)
        .unwrap();
    for i in 0..n {
        assert!((ex.beta.row(i).sum() - 1.0).abs() < 1e-12);
    }
    // Row-permutation check of exactness at this size: transpose-symmetric input ⇒ symmetric β.
    let sym = DMatrix::from_fn(n, n, |i, j| -0.3 * ((i as f64 - j as f64).abs()));
    let lm = LikelihoodMatrix::new(sym).unwrap();
    let b = Jpda::new(0.9, 0.99, 1e-2)
        .unwrap()
        .with_solver(exact_solver())
        .associate(&lm, &pri)
        .unwrap();
    for i in 0..n {
        for j in 0..n {
            assert!((b.beta[(i, j + 1)] - b.beta[(j, i + 1)]).abs() < 1e-12);
        }
    }
}

fn well_formed(a: &quarry_core::Association, n: usize, m: usize) -> bool {
    a.beta.shape() == (n, m + 1)
        && !a.log_normaliser.is_nan()
        && (0..n).all(|i| {
            (a.beta.row(i).sum() - 1.0).abs() < 1e-6
                && a.beta
                    .row(i)
                    .iter()
                    .all(|b| b.is_finite() && *b >= -1e-12 && *b <= 1.0 + 1e-9)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    /// The fuzz target's contract on stable: arbitrary values and parameters never panic, and
    /// every successful result is well-formed.
    #[test]
    fn arbitrary_inputs_never_panic(n in 0usize..6, m in 0usize..7,
                                    vals in proptest::collection::vec(prop_oneof![
                                        2 => any::<f64>(), 2 => Just(NI), 3 => -50.0f64..5.0,
                                        1 => Just(-1e308), 1 => Just(f64::MIN_POSITIVE)], 42),
                                    ps in proptest::collection::vec(prop_oneof![
                                        Just(f64::NAN), Just(0.0), Just(1.0), Just(1.5), 0.0f64..1.0], 16),
                                    kappa in prop_oneof![Just(0.0), Just(f64::INFINITY), 1e-300f64..1e3],
                                    method in 0u8..4, k in 0usize..5, budget in 1usize..500) {
        let lik = DMatrix::from_row_slice(n, m, &vals[..n * m]);
        let Ok(lm) = LikelihoodMatrix::new(lik) else { return Ok(()) };
        let pri: Vec<TrackPrior> = (0..n)
            .map(|i| TrackPrior {
                existence: (i % 2 == 0).then_some(ps[i]),
                detection: (i % 3 == 0).then_some(ps[i + 6]),
            })
            .collect();
        let method = match method { 0 => Method::Auto, 1 => Method::Exact, 2 => Method::KBest { k }, _ => Method::Lbp };
        let solver = Solver { method, max_states: budget, ..Solver::default() };
        let (pd, pg) = (ps[12], ps[13]);
        if let Ok(j) = Jpda::new(pd, pg, kappa)
            && let Ok(a) = j.with_solver(solver).associate(&lm, &pri)
        {
            prop_assert!(well_formed(&a, n, m));
        }
        if let Ok(j) = Jipda::new(pd, pg, kappa)
            && let Ok(a) = j.with_survival(ps[14]).with_solver(solver).associate(&lm, &pri)
        {
            prop_assert!(well_formed(&a, n, m));
            prop_assert!(a.existence.unwrap().iter().all(|e| (0.0..=1.0).contains(e)));
        }
        if let Ok(a) = (Pda { pd, prob_gate: pg, clutter_density: kappa }).associate(&lm, &pri) {
            prop_assert!(well_formed(&a, n, m));
        }
        if let Ok(g) = Gnn::new(pd, pg, kappa)
            && let Ok(a) = g.associate(&lm, &pri)
        {
            prop_assert!(well_formed(&a, n, m));
        }
        if let Ok(a) = PaperLikelihood.associate(&lm, &pri) { prop_assert!(well_formed(&a, n, m)); }
    }
}

/// Fuzz regressions (fuzz/regressions/associator): a subnormal clutter density makes the
/// detection scores ~e^711 times the miss scores. The scaled miss weights were subnormals (a
/// few bits of precision) and the level scale e^{ln c} overflowed: β came out as inf, or rows
/// summed to 0.99997. Every method must return finite rows that sum to 1, and the exact ones
/// the two tracks sharing the one detection equally (LBP and k-best work on the scaled scores
/// as f64 and may not: documented in quarry_assoc::engine).
#[test]
fn extreme_score_ratios_give_finite_marginals() {
    let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(2, 1, &[2.1e-314, 3.2e-57])).unwrap();
    let pri = [TrackPrior::default(); 2];
    for method in ALL_METHODS {
        let solver = Solver {
            method,
            ..Solver::default()
        };
        for kappa in [2.35e-310, 1e-300, f64::MIN_POSITIVE, 5e-324] {
            let a = Jpda::new(0.2, 0.2, kappa)
                .unwrap()
                .with_solver(solver)
                .associate(&lik, &pri)
                .unwrap();
            assert_rows_sum_to_one(&a.beta, &format!("{method:?} κ={kappa:e}"));
            if matches!(method, Method::Auto | Method::Exact) {
                for i in 0..2 {
                    assert!(
                        (a.beta[(i, 1)] - 0.5).abs() < 1e-9,
                        "{method:?} κ={kappa:e}: {}",
                        a.beta
                    );
                }
            }
        }
    }
}

/// JPDA with (P_D, P_G, κ) and the given method.
fn jpda_with(
    method: Method,
    (pd, pg, kappa): (f64, f64, f64),
    lik: &LikelihoodMatrix,
    pri: &[TrackPrior],
) -> quarry_core::Association {
    Jpda::new(pd, pg, kappa)
        .unwrap()
        .with_solver(Solver {
            method,
            ..Solver::default()
        })
        .associate(lik, pri)
        .unwrap()
}

const ALL_METHODS: [Method; 4] = [
    Method::Auto,
    Method::Exact,
    Method::Lbp,
    Method::KBest { k: 64 },
];

fn assert_rows_sum_to_one(beta: &DMatrix<f64>, what: &str) {
    for i in 0..beta.nrows() {
        let row: Vec<f64> = beta.row(i).iter().copied().collect();
        assert!(
            row.iter()
                .all(|b| b.is_finite() && (-1e-12..=1.0 + 1e-9).contains(b)),
            "{what}: row {i} = {row:?}"
        );
        assert!(
            (row.iter().sum::<f64>() - 1.0).abs() < 1e-9,
            "{what}: row {i} = {row:?}"
        );
    }
}

/// The second fuzz input: three tracks, two detections, κ = 1.6e-319: every joint event
/// leaves a track missed, at a score e^-733 below its row's best.
#[test]
fn every_event_with_a_tiny_score_still_gives_rows_summing_to_one() {
    let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(
        3,
        2,
        &[-1.8e-6, -48.83, 0.0, 0.0, 0.0, 0.0],
    ))
    .unwrap();
    let pri = [TrackPrior::default(); 3];
    for method in ALL_METHODS {
        let a = jpda_with(method, (0.945, 0.486, 1.5745e-319), &lik, &pri);
        assert_rows_sum_to_one(&a.beta, &format!("{method:?}"));
    }
}

/// The third fuzz input: 8 × 8 log-likelihoods up to 2.5e257 (column-major). Products of
/// several tiny scaled scores underflowed: rows summed to 0.31 or 0.
#[test]
fn products_of_many_tiny_scores_do_not_underflow() {
    const NI: f64 = f64::NEG_INFINITY;
    #[rustfmt::skip]
    let cols = [
        -35.466, -35.466, 1.1945302443632496e103, 1.1945302443632241e103, NI, NI, -43.69, -61.166,
        -35.466, -35.466, NI, NI, NI, -3.8136786330219526e-103, -21.845, -61.166,
        -35.466, -35.466, -8.618, NI, -43.69, -21.845, NI, -61.166,
        -35.466, 2.4712980764242054e257, NI, -61.166, NI, NI, 1.9131153006102492e102, -61.166,
        -35.466, NI, -21.845, -61.166, -21.93, NI, NI, -61.166,
        -35.466, 4.00853087e-316, NI, -61.166, NI, 1.1945305291615224e103, NI, -61.166,
        -35.466, 1.2241742066932781e103, NI, NI, NI, NI, -61.166, -61.166,
        -35.466, NI, NI, NI, NI, NI, -61.166, -61.166,
    ];
    let lik = LikelihoodMatrix::new(DMatrix::from_column_slice(8, 8, &cols)).unwrap();
    let pri = [TrackPrior::default(); 8];
    for method in ALL_METHODS {
        let a = jpda_with(method, (0.9333, 0.9333, 61.166), &lik, &pri);
        assert_rows_sum_to_one(&a.beta, &format!("{method:?}"));
    }
}

/// Two tracks want the same detection with log-likelihoods 800 and 900: the second wins by a
/// factor e^100, and the first then chooses between its miss (0.19) and its other detection
/// (0.9 e^-3) exactly as if alone. Beyond f64 in the linear domain; exact in the log domain.
#[test]
fn exact_marginals_hold_when_scores_differ_by_more_than_f64_can_hold() {
    const NI: f64 = f64::NEG_INFINITY;
    let lik = LikelihoodMatrix::new(DMatrix::from_row_slice(
        2,
        3,
        &[800.0, -3.0, NI, 900.0, NI, -5.0],
    ))
    .unwrap();
    let (miss, other) = (1.0 - 0.81, 0.9 * (-3.0f64).exp());
    for method in [Method::Auto, Method::Exact] {
        let a = Jpda::new(0.9, 0.9, 1.0)
            .unwrap()
            .with_solver(Solver {
                method,
                ..Solver::default()
            })
            .associate(&lik, &[TrackPrior::default(); 2])
            .unwrap();
        assert!(a.beta[(1, 1)] > 1.0 - 1e-12, "{}", a.beta);
        assert!(
            (a.beta[(0, 0)] - miss / (miss + other)).abs() < 1e-9,
            "{}",
            a.beta
        );
        assert!(
            (a.beta[(0, 2)] - other / (miss + other)).abs() < 1e-9,
            "{}",
            a.beta
        );
        assert!(a.log_normaliser.is_finite());
    }
}
