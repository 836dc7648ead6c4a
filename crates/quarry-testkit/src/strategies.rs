//! Proptest strategies shared by the quarry tests.

use std::ops::{Range, RangeInclusive};

use nalgebra::{DMatrix, SMatrix, SVector};
use proptest::prelude::*;
use quarry_core::Plane;

/// A `w x h` plane with both sides drawn from `sides` and every pixel from `pixel`.
///
/// ```
/// use proptest::prelude::*;
/// proptest!(|(p in quarry_testkit::strategies::plane(2..=9, 0u8..4))| {
///     prop_assert!(p.width >= 2 && p.height <= 9 && p.data.iter().all(|&v| v < 4));
/// });
/// ```
pub fn plane<S>(sides: RangeInclusive<u32>, pixel: S) -> impl Strategy<Value = Plane<S::Value>>
where
    S: Strategy + Clone,
    S::Value: Clone,
{
    (sides.clone(), sides).prop_flat_map(move |(w, h)| {
        proptest::collection::vec(pixel.clone(), (w * h) as usize)
            .prop_map(move |d| Plane::from_fn(w, h, |x, y| d[(y * w + x) as usize].clone()))
    })
}

/// The SPD matrix `Q diag(10^log10_eigs) Q^T` (symmetrised), with `Q` the product of the Givens
/// rotations by `angles[k]` in the planes `(0, 1), (0, 2), ..., (D-2, D-1)`, in that order.
///
/// `angles` holds `D (D - 1) / 2` angles; the eigenvalues are exactly `10^log10_eigs` up to
/// rounding, so the condition number is under control.
pub fn spd_from_rotations<const D: usize>(
    angles: &[f64],
    log10_eigs: &[f64; D],
) -> SMatrix<f64, D, D> {
    assert_eq!(
        angles.len(),
        D * (D - 1) / 2,
        "one angle per plane (i, j), i < j"
    );
    let mut q = SMatrix::<f64, D, D>::identity();
    let planes = (0..D).flat_map(|i| (i + 1..D).map(move |j| (i, j)));
    for (&angle, (i, j)) in angles.iter().zip(planes) {
        let (s, c) = angle.sin_cos();
        let mut g = SMatrix::<f64, D, D>::identity();
        g[(i, i)] = c;
        g[(j, j)] = c;
        g[(i, j)] = -s;
        g[(j, i)] = s;
        q = g * q;
    }
    let d = SMatrix::<f64, D, D>::from_diagonal(&SVector::<f64, D>::from_iterator(
        log10_eigs.iter().map(|v| 10f64.powf(*v)),
    ));
    let p = q * d * q.transpose();
    (p + p.transpose()) * 0.5
}

/// Random SPD `D x D` matrices: [`spd_from_rotations`] with angles in `[-3.2, 3.2)` and
/// log10-eigenvalues in `log10_eigs`.
pub fn spd_matrix<const D: usize>(
    log10_eigs: Range<f64>,
) -> impl Strategy<Value = SMatrix<f64, D, D>> {
    (
        proptest::collection::vec(-3.2..3.2f64, D * (D - 1) / 2),
        proptest::array::uniform::<_, D>(log10_eigs),
    )
        .prop_map(|(angles, eigs)| spd_from_rotations(&angles, &eigs))
}

/// Static vectors with every entry drawn from `entries` (a finite range: no NaN, no infinity).
pub fn finite_vector<const D: usize>(
    entries: Range<f64>,
) -> impl Strategy<Value = SVector<f64, D>> {
    proptest::array::uniform::<_, D>(entries).prop_map(SVector::from)
}

/// Dense matrices with `rows x cols` drawn from the two ranges and entries from `entry`, filled
/// row by row.
pub fn matrix<S>(
    rows: Range<usize>,
    cols: Range<usize>,
    entry: S,
) -> impl Strategy<Value = DMatrix<f64>>
where
    S: Strategy<Value = f64> + Clone,
{
    (rows, cols).prop_flat_map(move |(n, m)| {
        proptest::collection::vec(entry.clone(), n * m)
            .prop_map(move |v| DMatrix::from_row_slice(n, m, &v))
    })
}

/// An `n x m` matrix of log-likelihoods `ln g` for association: about 60 % of the pairs gated
/// (a value in `[-12, 0)`), the others `-inf` (outside the gate).
pub fn gated_log_likelihoods(n: usize, m: usize) -> impl Strategy<Value = DMatrix<f64>> {
    proptest::collection::vec(
        prop_oneof![3 => -12.0f64..0.0, 2 => Just(f64::NEG_INFINITY)],
        n * m,
    )
    .prop_map(move |v| DMatrix::from_row_slice(n, m, &v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spd_from_rotations_has_the_given_eigenvalues() {
        let p = spd_from_rotations::<3>(&[0.3, -1.0, 2.0], &[0.0, 1.0, -1.0]);
        let mut e: Vec<f64> = p.symmetric_eigenvalues().iter().copied().collect();
        e.sort_by(f64::total_cmp);
        for (got, want) in e.iter().zip([0.1, 1.0, 10.0]) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
        assert_eq!(p, p.transpose());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        #[test]
        fn shapes_and_ranges(
            p in plane(2..=5, 0u8..3),
            v in finite_vector::<3>(-1.0..1.0),
            m in matrix(1..4, 2..3, 0.0f64..1.0),
            l in gated_log_likelihoods(2, 3),
        ) {
            prop_assert!((2..=5).contains(&p.width) && (2..=5).contains(&p.height));
            prop_assert_eq!(p.data.len(), (p.width * p.height) as usize);
            prop_assert!(v.iter().all(|x| (-1.0..1.0).contains(x)));
            prop_assert!((1..4).contains(&m.nrows()) && m.ncols() == 2);
            prop_assert_eq!(l.shape(), (2, 3));
            prop_assert!(l.iter().all(|&x| x == f64::NEG_INFINITY || (-12.0..0.0).contains(&x)));
        }
    }
}
