//! Small fixed-size matrix kernels for the filter hot path.
//!
//! nalgebra's generic `Matrix * Matrix` on static sizes goes through its general `gemm` path,
//! which is not inlined for 4 × 4 operands: on a 4-state Kalman step it was half the
//! instructions. These kernels are plain loops over the column-major arrays of
//! [`SMatrix`]; with the sizes known at compile time the compiler unrolls and vectorises them.
//! They compute the same sums in the same order as the textbook definition (`k` innermost
//! accumulation order differs from nalgebra's only by rounding, which the tests bound).

// `#[inline(always)]` is measured, not hopeful: with `#[inline]` the 4 × 4 products stayed out of
// line in `ekf::update` (callgrind: 1,760 instead of 1,400 instructions per KF step). Index loops
// over the fixed arrays are the clearest form of these kernels and unroll completely. Triangular
// loops are written `0..j + 1`, never `0..=j`: `RangeInclusive` did not unroll and nearly
// doubled the prediction (514 against 273 instructions per CV step, callgrind).
#![allow(
    clippy::inline_always,
    clippy::needless_range_loop,
    clippy::range_plus_one
)]

use nalgebra::{SMatrix, SVector};

/// `A B`.
#[inline(always)]
pub(crate) fn mul<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, K, C>,
) -> SMatrix<f64, R, C> {
    let a = &a.data.0;
    let b = &b.data.0;
    let mut out = SMatrix::<f64, R, C>::zeros();
    let o = &mut out.data.0;
    for j in 0..C {
        for k in 0..K {
            let bkj = b[j][k];
            for i in 0..R {
                o[j][i] += a[k][i] * bkj;
            }
        }
    }
    out
}

/// `A Bᵀ` skipping the zero entries of `B`.
///
/// Meant for a structured `B` (a motion or measurement Jacobian): once the model is inlined the
/// compiler knows which entries are the literal `0.0` and removes their work, and multiplications
/// by a literal `1.0` fold away, so a constant-velocity `F` or a position `H` costs what its
/// non-zeros cost. For a dense `B` the test is one predictable branch per entry. Skipping
/// `a · 0` differs from computing it only when `a` is not finite, which the filters reject.
#[inline(always)]
pub(crate) fn mul_tr_sparse<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, C, K>,
) -> SMatrix<f64, R, C> {
    let a = &a.data.0;
    let b = &b.data.0;
    let mut out = SMatrix::<f64, R, C>::zeros();
    let o = &mut out.data.0;
    for j in 0..C {
        for k in 0..K {
            let bjk = b[k][j];
            if bjk != 0.0 {
                for i in 0..R {
                    o[j][i] += a[k][i] * bjk;
                }
            }
        }
    }
    out
}

/// `ln det S = 2 ln Π L_ii` from the Cholesky diagonal: one logarithm, falling back to a sum
/// of logarithms when the product under- or overflows.
#[inline(always)]
pub(crate) fn log_det_from_chol_diag<const Z: usize>(diag: &[f64; Z]) -> f64 {
    let prod: f64 = diag.iter().product();
    if prod.is_normal() {
        2.0 * prod.ln()
    } else {
        2.0 * diag.iter().map(|v| v.ln()).sum::<f64>()
    }
}

/// `atᵀ bᵀ + add` for a product known to be symmetric (`F P Fᵀ + Q`, `H P Hᵀ + R`): only the
/// upper triangle is accumulated (`i ≤ j`), then mirrored, so the result is exactly symmetric and
/// costs about 60 % of the full product. `at` is the transposed left factor (`P Fᵀ` for `F P`), so
/// no transpose is ever materialised; zeros of `b` (a Jacobian's structure, constant once the
/// model is inlined) are skipped. Only the upper triangle of `add` is read.
#[inline(always)]
pub(crate) fn sym_tr_mul_add<const K: usize, const R: usize>(
    at: &SMatrix<f64, K, R>,
    b: &SMatrix<f64, R, K>,
    add: &SMatrix<f64, R, R>,
) -> SMatrix<f64, R, R> {
    let at = &at.data.0;
    let b = &b.data.0;
    let mut out = *add;
    let o = &mut out.data.0;
    for j in 0..R {
        for k in 0..K {
            let bjk = b[k][j];
            if bjk != 0.0 {
                for i in 0..j + 1 {
                    o[j][i] += at[i][k] * bjk;
                }
            }
        }
    }
    mirror_upper(&mut out);
    out
}

/// The Joseph-form posterior covariance `P + C Kᵀ − K Mᵀ` with `M = P Hᵀ` and `C = K S − M`,
/// upper triangle accumulated and mirrored. Expanded, this is `P − K Mᵀ − M Kᵀ + K S Kᵀ`, which
/// equals `(I − KH) P (I − KH)ᵀ + K R Kᵀ` for *any* gain `K` (not only the optimal one): the same
/// first-order insensitivity to errors in `K`, at 40 % of the cost of forming `I − KH`.
#[inline(always)]
pub(crate) fn joseph_sym<const D: usize, const Z: usize>(
    p: &SMatrix<f64, D, D>,
    k: &SMatrix<f64, D, Z>,
    m: &SMatrix<f64, D, Z>,
    c: &SMatrix<f64, D, Z>,
) -> SMatrix<f64, D, D> {
    let kd = &k.data.0;
    let md = &m.data.0;
    let cd = &c.data.0;
    let mut out = *p;
    let o = &mut out.data.0;
    for j in 0..D {
        for a in 0..Z {
            let kja = kd[a][j];
            let mja = md[a][j];
            for i in 0..j + 1 {
                o[j][i] += cd[a][i] * kja - kd[a][i] * mja;
            }
        }
    }
    mirror_upper(&mut out);
    out
}

/// Copies the upper triangle onto the lower one.
#[inline(always)]
fn mirror_upper<const D: usize>(a: &mut SMatrix<f64, D, D>) {
    let o = &mut a.data.0;
    for j in 0..D {
        for i in 0..j {
            o[i][j] = o[j][i];
        }
    }
}

/// The Cholesky factor `S = L Lᵀ` of a small symmetric positive definite matrix, with the
/// reciprocals of its diagonal (so that solves multiply instead of divide).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Chol<const Z: usize> {
    /// Lower triangle, column-major (`l[j][i]` is `L_ij`, `i >= j`); the upper part is zero.
    l: [[f64; Z]; Z],
    inv_diag: [f64; Z],
}

impl<const Z: usize> Chol<Z> {
    /// Factors `s` (only its lower triangle is read). `None` unless every pivot is positive and
    /// finite.
    #[inline(always)]
    pub(crate) fn new(s: &SMatrix<f64, Z, Z>) -> Option<Self> {
        let s = &s.data.0;
        let mut l = [[0.0; Z]; Z];
        let mut inv_diag = [0.0; Z];
        for j in 0..Z {
            let mut d = s[j][j];
            for k in 0..j {
                d -= l[k][j] * l[k][j];
            }
            // `!(d > 0)` also rejects NaN.
            if !(d > 0.0 && d.is_finite()) {
                return None;
            }
            let ljj = d.sqrt();
            l[j][j] = ljj;
            let inv = 1.0 / ljj;
            inv_diag[j] = inv;
            for i in (j + 1)..Z {
                let mut v = s[j][i];
                for k in 0..j {
                    v -= l[k][i] * l[k][j];
                }
                l[j][i] = v * inv;
            }
        }
        Some(Self { l, inv_diag })
    }

    /// `ln det S = 2 Σ ln L_ii`, with one logarithm while the product stays normal.
    #[inline(always)]
    pub(crate) fn log_det(&self) -> f64 {
        log_det_from_chol_diag(&self.diag())
    }

    /// The factor's diagonal `L_ii`.
    #[inline(always)]
    pub(crate) fn diag(&self) -> [f64; Z] {
        let mut d = [0.0; Z];
        for j in 0..Z {
            d[j] = self.l[j][j];
        }
        d
    }

    /// `S⁻¹ B` for a `Z × C` right-hand side.
    #[inline(always)]
    pub(crate) fn solve<const C: usize>(&self, b: &SMatrix<f64, Z, C>) -> SMatrix<f64, Z, C> {
        let mut x = *b;
        for c in 0..C {
            self.solve_in_place(&mut x.data.0[c]);
        }
        x
    }

    /// `S⁻¹ b` for one column, in place: forward then backward substitution.
    #[inline(always)]
    pub(crate) fn solve_in_place(&self, x: &mut [f64; Z]) {
        let l = &self.l;
        for i in 0..Z {
            let mut v = x[i];
            for k in 0..i {
                v -= l[k][i] * x[k];
            }
            x[i] = v * self.inv_diag[i];
        }
        for i in (0..Z).rev() {
            let mut v = x[i];
            for k in (i + 1)..Z {
                v -= l[i][k] * x[k];
            }
            x[i] = v * self.inv_diag[i];
        }
    }

    /// `νᵀ S⁻¹ ν = |L⁻¹ ν|²` (one forward substitution).
    #[inline(always)]
    pub(crate) fn quad(&self, nu: &SVector<f64, Z>) -> f64 {
        let l = &self.l;
        let mut y = nu.data.0[0];
        let mut acc = 0.0;
        for i in 0..Z {
            let mut v = y[i];
            for k in 0..i {
                v -= l[k][i] * y[k];
            }
            let w = v * self.inv_diag[i];
            y[i] = w;
            acc += w * w;
        }
        acc
    }
}

/// `A x`.
#[inline(always)]
pub(crate) fn mul_vec<const R: usize, const K: usize>(
    a: &SMatrix<f64, R, K>,
    x: &SVector<f64, K>,
) -> SVector<f64, R> {
    let a = &a.data.0;
    let x = &x.data.0[0];
    let mut out = SVector::<f64, R>::zeros();
    let o = &mut out.data.0[0];
    for k in 0..K {
        for i in 0..R {
            o[i] += a[k][i] * x[k];
        }
    }
    out
}

/// `(A + Aᵀ) / 2`.
#[inline(always)]
pub(crate) fn symmetrise<const D: usize>(a: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
    let mut out = *a;
    let o = &mut out.data.0;
    for j in 0..D {
        for i in (j + 1)..D {
            let v = 0.5 * (o[j][i] + o[i][j]);
            o[j][i] = v;
            o[i][j] = v;
        }
    }
    out
}

/// Whether every entry is finite, without early exit (branch-free, vectorisable).
#[inline(always)]
pub(crate) fn finite(s: &[f64]) -> bool {
    s.iter().fold(true, |acc, v| acc & v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2x4, Matrix4, Matrix4x2, Vector4};
    use proptest::prelude::*;

    fn m4(v: &[f64]) -> Matrix4<f64> {
        Matrix4::from_column_slice(&v[..16])
    }

    proptest! {
        #[test]
        fn kernels_equal_nalgebra(v in proptest::collection::vec(-10.0..10.0f64, 48)) {
            let a = m4(&v[..16]);
            let b = m4(&v[16..32]);
            let c = Matrix4x2::from_column_slice(&v[32..40]);
            let d = Matrix2x4::from_column_slice(&v[40..48]);
            let x = Vector4::new(v[0], v[5], v[9], v[13]);
            prop_assert!((mul(&a, &b) - a * b).amax() < 1e-12);
                        prop_assert!((mul(&a, &c) - a * c).amax() < 1e-12);
            prop_assert!((mul(&d, &a) - d * a).amax() < 1e-12);
                        prop_assert!((mul_vec(&a, &x) - a * x).amax() < 1e-12);
            let spd = a * a.transpose() + Matrix4::identity();
            let mut sparse = b;
            sparse[(1, 2)] = 0.0;
            sparse[(3, 0)] = 0.0;
            prop_assert!((mul_tr_sparse(&a, &sparse) - a * sparse.transpose()).amax() < 1e-12);
            prop_assert!((mul_tr_sparse(&d.transpose(), &d.transpose()) - d.transpose() * d).amax() < 1e-12);
            let ch = Chol::new(&spd).unwrap();
            let na = nalgebra::Cholesky::new(spd).unwrap();
            prop_assert!((ch.solve(&b) - na.solve(&b)).amax() < 1e-9 * (1.0 + na.solve(&b).amax()));
            prop_assert!((ch.quad(&x) - x.dot(&na.solve(&x))).abs() < 1e-9 * (1.0 + x.norm_squared()));
            prop_assert!((ch.log_det() - spd.determinant().ln()).abs() < 1e-9);
            let q = a + a.transpose();
            let sym = sym_tr_mul_add(&a.transpose(), &sparse, &q);
            let full = a * sparse.transpose() + q;
            prop_assert!((sym.upper_triangle() - full.upper_triangle()).amax() < 1e-9 * (1.0 + full.amax()));
            prop_assert_eq!(sym, sym.transpose());
            let (k, m) = (c, Matrix4x2::from_column_slice(&v[40..48]));
            let cm = Matrix4x2::from_column_slice(&v[24..32]);
            let jos = joseph_sym(&spd, &k, &m, &cm);
            let jf = spd + cm * k.transpose() - k * m.transpose();
            prop_assert!((jos.upper_triangle() - jf.upper_triangle()).amax() < 1e-9 * (1.0 + jf.amax()));
            prop_assert_eq!(jos, jos.transpose());
            let s = symmetrise(&a);
            prop_assert!((s - (a + a.transpose()) * 0.5).amax() < 1e-15);
            prop_assert_eq!(s, s.transpose());
        }
    }

    #[test]
    fn chol_rejects_indefinite_and_nan() {
        assert!(Chol::new(&Matrix4::<f64>::zeros()).is_none());
        let mut m = Matrix4::<f64>::identity();
        m[(2, 2)] = -1.0;
        assert!(Chol::new(&m).is_none());
        m[(2, 2)] = f64::NAN;
        assert!(Chol::new(&m).is_none());
        m[(2, 2)] = f64::INFINITY;
        assert!(Chol::new(&m).is_none());
    }

    #[test]
    fn finite_detects_every_position() {
        let mut v = [1.0; 9];
        assert!(finite(&v));
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for i in 0..v.len() {
                v[i] = bad;
                assert!(!finite(&v));
                v[i] = 1.0;
            }
        }
    }
}
