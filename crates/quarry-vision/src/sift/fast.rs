//! Speed kernels of the SIFT scale space: a Gaussian blur that computes exactly what
//! [`crate::blur::gaussian_blur_f32`] computes (same f32 kernel, same reflect-101 border, the
//! same sequence of IEEE operations for every output value, so the result is bit-identical)
//! but laid out for speed:
//!
//! - the padded row is built with one copy of the interior and border look-ups only for the `r`
//!   pixels at each end (instead of a border look-up per pixel), and the row kernel of
//!   [`crate::blur`] runs over all of it, edges included;
//! - both passes are register-blocked: a block of [`LANES`] outputs is accumulated over all taps
//!   in registers (`acc = k0·c; acc += k_j·(a + b)` for j = 1..=r, in that order, exactly the
//!   reference's per-pixel order), so the output is written once instead of once per tap;
//! - the loops are compiled three times (baseline x86-64, AVX2, AVX-512F) and chosen at run time
//!   ([`crate::simd`]). Rust never contracts `a * b + c` into a fused multiply-add, so the
//!   three builds perform the same IEEE operations and give bit-identical results;
//! - no finiteness scan (the scale space checks its input once; blurs of finite images are
//!   finite).
//!
//! With the `parallel` feature both passes are split over bands of rows with rayon (images
//! below [`PAR_MIN_PIXELS`] run on the calling thread); every output value is computed by the
//! same operations whatever the thread count.
//!
//! Why a second blur and not [`crate::blur`]'s kernels: the results would be the same (the test
//! below checks bit-identity against `gaussian_blur_f32` for every build), but the layout is
//! not. Routing the pyramid through `blur::blur_rows` (the generic f32/f64, any-border kernels,
//! AVX2 or AVX-512F) was measured on 2026-12-02 on `photo_gray.png` (`sift_stage_times`, one
//! thread, 45 runs each, load ≈ 8 on 2 cores): scale space median 44.9–47.1 ms against
//! 41.9–42.2 ms here, about 4 % of detect + describe, which is the margin by which SIFT meets
//! its single-thread goal against OpenCV (`docs/PERFORMANCE.md`). The gains here are the
//! column strips of the vertical pass (its `2r + 1` rows stay in L1), the rows padded
//! once, one scratch for the whole pyramid and no rayon hand-off for small octaves. The two
//! share the instruction-set dispatch (`crate::simd`); moving this layout into `blur.rs` for
//! all callers would leave one kernel instead of two.

use crate::VisionError;
use crate::blur::{Border, GaussianKernel};
use crate::simd::{Isa, isa, multiversion};
use quarry_core::Plane;

/// Outputs accumulated together in registers.
const LANES: usize = 32;

/// Images with fewer pixels are blurred on the calling thread (task overhead dominates).
#[cfg(feature = "parallel")]
const PAR_MIN_PIXELS: usize = 128 * 128;

/// Rows per parallel task.
#[cfg(feature = "parallel")]
const ROWS_PER_TASK: usize = 16;

/// The half kernel `k_0 … k_r` of `cv2.GaussianBlur(.., (0, 0), sigma)` on float images,
/// rounded to f32 (as [`crate::blur::gaussian_blur_f32`]).
pub(super) fn half_kernel(sigma: f64) -> Result<Vec<f32>, VisionError> {
    let k = GaussianKernel::new(sigma)?;
    let r = k.radius();
    Ok(k.weights[r..].iter().map(|&v| v as f32).collect())
}

/// Blurs `src` (finite values, at least 1×1) with the half kernel `k`; bit-identical to
/// [`crate::blur::gaussian_blur_f32`] with the same σ.
/// `tmp` is scratch (grown as needed, its contents are overwritten).
pub(super) fn blur(src: &Plane<f32>, k: &[f32], tmp: &mut Vec<f32>) -> Plane<f32> {
    let (w, h) = (src.width as usize, src.height as usize);
    if tmp.len() < w * h {
        tmp.resize(w * h, 0.0);
    }
    let tmp = &mut tmp[..w * h];
    let mut out = vec![0f32; w * h];
    let level = isa();
    horizontal(&src.data, tmp, w, k, level);
    vertical(tmp, &mut out, w, h, k, level);
    Plane {
        width: src.width,
        height: src.height,
        data: out,
    }
}

fn horizontal(src: &[f32], dst: &mut [f32], w: usize, k: &[f32], level: Isa) {
    let run = |s: &[f32], d: &mut [f32]| {
        let mut pad = Vec::with_capacity(w + 2 * (k.len() - 1));
        dispatch_h(level, s, d, w, k, &mut pad);
    };
    #[cfg(feature = "parallel")]
    if src.len() >= PAR_MIN_PIXELS {
        use rayon::prelude::*;
        src.par_chunks(w * ROWS_PER_TASK)
            .zip(dst.par_chunks_mut(w * ROWS_PER_TASK))
            .for_each(|(s, d)| run(s, d));
        return;
    }
    run(src, dst);
}

fn vertical(src: &[f32], dst: &mut [f32], w: usize, h: usize, k: &[f32], level: Isa) {
    let run = |y0: usize, d: &mut [f32]| dispatch_v(level, src, d, w, h, y0, k);
    #[cfg(feature = "parallel")]
    if src.len() >= PAR_MIN_PIXELS {
        use rayon::prelude::*;
        dst.par_chunks_mut(w * ROWS_PER_TASK)
            .enumerate()
            .for_each(|(band, d)| run(band * ROWS_PER_TASK, d));
        return;
    }
    run(0, dst);
}

multiversion!(avx512, avx2: fn dispatch_h => h_body(
    src: &[f32],
    dst: &mut [f32],
    w: usize,
    k: &[f32],
    pad: &mut Vec<f32>,
));

multiversion!(avx512, avx2: fn dispatch_v => v_body(
    src: &[f32],
    dst: &mut [f32],
    w: usize,
    h: usize,
    y0: usize,
    k: &[f32],
));

/// Horizontal pass over whole rows of `src` into `dst` (same length, a multiple of `w`).
/// Each row is copied once into `pad` with its reflect-101 border (`r` values at each end) and
/// blurred by [`crate::blur`]'s row kernel (register blocks of 32 outputs, the remainder
/// taps-outer), so every output, the `r` at each end included, comes from a vectorised loop.
/// The former in-place interior loop with scalar edges was not vectorised by LLVM at all
/// (scalar `vmulss`/`vaddss` in `perf annotate`) and was 44 % of a crop's SIFT time.
// Inlined into the builds of `multiversion!` so that the loops are compiled for each ISA there.
#[allow(clippy::inline_always)]
#[inline(always)]
fn h_body(src: &[f32], dst: &mut [f32], w: usize, k: &[f32], pad: &mut Vec<f32>) {
    let r = k.len() - 1;
    for (s, d) in src.chunks_exact(w).zip(dst.chunks_exact_mut(w)) {
        // pad[q] = s[border(q − r)], q < w + 2r.
        pad.clear();
        pad.extend((0..r).map(|q| s[Border::Reflect101.interpolate(q as isize - r as isize, w)]));
        pad.extend_from_slice(s);
        pad.extend((w..w + r).map(|x| s[Border::Reflect101.interpolate(x as isize, w)]));
        crate::blur::blur_row_body(pad, d, k);
    }
}

/// Columns processed together by the vertical pass: the `2r + 1` source rows of a strip stay
/// in the L1 cache from one output row to the next.
const STRIP: usize = 8 * LANES;

/// Vertical pass: rows `y0..` of the output (as many as `dst` holds) from the whole `src`,
/// strip by strip of [`STRIP`] columns.
#[allow(clippy::inline_always)]
#[inline(always)]
fn v_body(src: &[f32], dst: &mut [f32], w: usize, h: usize, y0: usize, k: &[f32]) {
    let k0 = k[0];
    let row = |y: isize| -> &[f32] {
        let yy = Border::Reflect101.interpolate(y, h);
        &src[yy * w..(yy + 1) * w]
    };
    let n_rows = dst.len() / w;
    // The (reflected) source rows y0 − r ..= y0 + n_rows − 1 + r, once each: output row i reads
    // the window rows[i ..= i + 2r], its centre at i + r and tap j's pair at i + r ∓ j.
    let r = k.len() - 1;
    let rows: Vec<&[f32]> = (0..n_rows + 2 * r)
        .map(|i| row((y0 + i) as isize - r as isize))
        .collect();
    let mut x0 = 0;
    while x0 < w {
        let x1 = (x0 + STRIP).min(w);
        for (i, d) in dst.chunks_exact_mut(w).enumerate() {
            let win = &rows[i..=i + 2 * r];
            let mut x = x0;
            while x + LANES <= x1 {
                v_block::<LANES>(&mut d[x..x + LANES], x, k0, &k[1..], win);
                x += LANES;
            }
            // The strip's last columns: blocks of 8, then single columns.
            while x + 8 <= x1 {
                v_block::<8>(&mut d[x..x + 8], x, k0, &k[1..], win);
                x += 8;
            }
            for xx in x..x1 {
                let mut a = k0 * win[r][xx];
                for (j, &kj) in k[1..].iter().enumerate() {
                    a += kj * (win[r - 1 - j][xx] + win[r + 1 + j][xx]);
                }
                d[xx] = a;
            }
        }
        x0 = x1;
    }
}

/// `N` outputs of the vertical pass from column `x`: `k0·centre + Σ_j k_j·(up_j + down_j)`, in
/// the reference's order; `win` holds the `2r + 1` source rows, the centre in the middle.
#[allow(clippy::inline_always)]
#[inline(always)]
fn v_block<const N: usize>(d: &mut [f32], x: usize, k0: f32, k: &[f32], win: &[&[f32]]) {
    let r = k.len();
    let mut acc = [0f32; N];
    for (a, &v) in acc.iter_mut().zip(&win[r][x..x + N]) {
        *a = k0 * v;
    }
    for (j, &kj) in k.iter().enumerate() {
        let up = &win[r - 1 - j][x..x + N];
        let down = &win[r + 1 + j][x..x + N];
        for ((a, &u), &v) in acc.iter_mut().zip(up).zip(down) {
            *a += kj * (u + v);
        }
    }
    d.copy_from_slice(&acc);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit-identical to the reference blur, for every ISA build, sizes around the block width
    /// and kernels wider than the image.
    #[test]
    fn blur_is_bit_identical_to_reference() {
        let levels = Isa::all_supported();
        let mut seed = 12_345u32;
        for &(w, h) in &[
            (1usize, 1usize),
            (3, 2),
            (31, 7),
            (32, 5),
            (33, 40),
            (47, 3),
            (97, 65),
            (161, 30),
            (200, 150),
        ] {
            let img = Plane::from_fn(w as u32, h as u32, |_, _| {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (seed >> 8) as f32 / 65_536.0
            });
            for sigma in [0.7, 1.2263, 1.5450, 3.09, 6.0] {
                let want = crate::blur::gaussian_blur_f32(&img, sigma).unwrap();
                let k = half_kernel(sigma).unwrap();
                for &level in &levels {
                    let mut tmp = vec![0f32; w * h];
                    let mut out = vec![0f32; w * h];
                    horizontal(&img.data, &mut tmp, w, &k, level);
                    vertical(&tmp, &mut out, w, h, &k, level);
                    let same = out
                        .iter()
                        .zip(&want.data)
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                    assert!(same, "{w}x{h} sigma {sigma} {level:?}");
                }
                let mut scratch = vec![f32::NAN; 7];
                assert_eq!(blur(&img, &k, &mut scratch).data, want.data);
            }
        }
    }
}
