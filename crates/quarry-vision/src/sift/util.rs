//! Small helpers shared by the SIFT stages: OpenCV's rounding (`cvRound`), a libm-free floor,
//! OpenCV's `fastAtan2` and `exp32f`, branch-free min / max, and the cache-line touch that
//! makes the window loads of the histograms overlap.

/// Rounds half to even, as OpenCV's `cvRound` (for |v| < 2^22; larger values are already
/// integers and are returned by a plain cast).
#[inline]
pub(super) fn cv_round(v: f32) -> i32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5·2^23
    if v.abs() < 4_194_304.0 {
        ((v + MAGIC) - MAGIC) as i32
    } else {
        v as i32
    }
}

/// floor(v) for |v| < 2^31 without a libm call (the baseline x86-64 target has no `roundps`).
#[inline]
pub(super) fn floor_small(v: f32) -> f32 {
    let t = v as i32 as f32;
    if t > v { t - 1.0 } else { t }
}

/// OpenCV's `fastAtan2`: atan2(y, x) in degrees in [0, 360), polynomial approximation.
#[inline]
pub(crate) fn fast_atan2(y: f32, x: f32) -> f32 {
    const K: f32 = 180.0 / std::f32::consts::PI;
    const P1: f32 = 0.999_787_84 * K;
    const P3: f32 = -0.325_808_4 * K;
    const P5: f32 = 0.155_578_65 * K;
    const P7: f32 = -0.044_326_556 * K;
    // OpenCV adds (float)DBL_EPSILON to the denominator.
    const DBL_EPS: f32 = f64::EPSILON as f32;
    let ax = x.abs();
    let ay = y.abs();
    // Branch-free form of OpenCV's code (same operations, so loops over arrays vectorise).
    let swap = ax < ay;
    let num = if swap { ax } else { ay };
    let den = if swap { ay } else { ax };
    let c = num / (den + DBL_EPS);
    let c2 = c * c;
    let p = (((P7 * c2 + P5) * c2 + P3) * c2 + P1) * c;
    let a = if swap { 90.0 - p } else { p };
    let a = if x < 0.0 { 180.0 - a } else { a };
    if y < 0.0 { 360.0 - a } else { a }
}

/// exp(x) for f32 without a libm call (Cephes `expf` polynomial, relative error ≈ 1e-7, as
/// OpenCV's `exp32f`); branch-free so loops over arrays vectorise. Valid for x in [−87, 88].
#[inline]
pub(crate) fn fast_exp(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const C1: f32 = 0.693_359_4;
    const C2: f32 = -2.121_944_4e-4;
    const MAGIC: f32 = 12_582_912.0; // 1.5·2^23: adding it rounds to an integer
    let x = x.clamp(-87.0, 88.0);
    let t = x * LOG2E + MAGIC;
    let n = t - MAGIC;
    let g = x - n * C1 - n * C2;
    let p = ((((1.987_569_1e-4 * g + 1.398_199_9e-3) * g + 8.333_452e-3) * g + 4.166_579_6e-2) * g
        + 0.166_666_65)
        * g
        + 0.5;
    let y = p * g * g + g + 1.0;
    let e = (t.to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32);
    y * f32::from_bits(((e + 127) << 23) as u32)
}

#[inline]
pub(super) fn fmax(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

#[inline]
pub(super) fn fmin(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// Loads one value per cache line of the columns `c0..=c1` of rows `r0..=r1` (clipped to
/// the image) so that the cache misses of a keypoint's window overlap instead of arriving one
/// row at a time inside the gathering loop (a software prefetch without `unsafe`).
#[allow(clippy::inline_always)]
#[inline(always)]
pub(super) fn touch_window(
    data: &[f32],
    cols: usize,
    c0: i32,
    c1: i32,
    r0: i32,
    r1: i32,
    rows: i32,
) {
    const LINE: usize = 16;
    let (c0, c1) = (c0.max(0) as usize, c1.max(0) as usize);
    let (r0, r1) = (r0.max(0), r1.min(rows - 1));
    if c1 < c0 || r1 < r0 {
        return;
    }
    for r in r0 as usize..=r1 as usize {
        let row = &data[r * cols..(r + 1) * cols];
        let end = c1.min(cols - 1);
        let mut c = c0;
        while c <= end {
            std::hint::black_box(row[c]);
            c += LINE;
        }
        std::hint::black_box(row[end]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_atan2_matches_atan2() {
        for k in 0..3600 {
            let a = (k as f32) * 0.1f32.to_radians();
            let (y, x) = (a.sin() * 3.0, a.cos() * 3.0);
            let got = fast_atan2(y, x);
            let want = y.atan2(x).to_degrees().rem_euclid(360.0);
            let diff = (got - want).abs().min(360.0 - (got - want).abs());
            assert!(diff < 0.02, "{k}: {got} vs {want}");
        }
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
    }

    #[test]
    fn fast_exp_matches_exp() {
        for k in 0..=4000 {
            let x = -40.0 + k as f32 * 0.011;
            let (got, want) = (fast_exp(x), x.exp());
            assert!((got / want - 1.0).abs() < 3e-7, "{x}: {got} vs {want}");
        }
    }

    #[test]
    fn rounding_helpers() {
        for v in [
            -2.5f32, -1.5, -0.5, 0.5, 1.5, 2.5, 3.49, -3.51, 1e7, -1e7, 0.0,
        ] {
            assert_eq!(cv_round(v), v.round_ties_even() as i32, "{v}");
            assert_eq!(floor_small(v), v.floor(), "{v}");
        }
        for k in -2000..2000 {
            let v = k as f32 * 0.013;
            assert_eq!(floor_small(v), v.floor());
            assert_eq!(cv_round(v), v.round_ties_even() as i32);
        }
    }
}
