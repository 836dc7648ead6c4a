//! Separable Gaussian blur with OpenCV's kernel-size rule and border modes.
//!
//! [`gaussian_blur_f64`] and [`gaussian_blur_f32`] agree with
//! `cv2.GaussianBlur(img, (0, 0), sigma)` on `CV_64F` / `CV_32F` images (default border
//! `BORDER_REFLECT_101`): the kernel has `round(8σ + 1) | 1` taps (radius ≈ 4σ, the rule OpenCV
//! uses for float images), weights `exp(−j²/2σ²)` normalised to sum 1, the horizontal pass runs
//! first and the vertical one second. Unlike `imageproc::filter::gaussian_blur_f32` (radius ⌈2σ⌉)
//! nothing of the Gaussian's mass beyond 4σ is lost, which matters for the ramped segmentation
//! image of spec 004 §2.3.
//!
//! Implementation: the symmetric kernel is folded (`k_j (a_{x−j} + a_{x+j})`), each pass walks
//! contiguous rows with the taps in the outer loop and the pixels in the inner loop, so the inner
//! loops auto-vectorise and the vertical pass reads whole rows (cache-friendly). On x86-64 CPUs
//! with AVX2 the same loops are compiled a second time for AVX2 and chosen at run time
//! (`crate::simd`); Rust never contracts `a * b + c` into FMA, so both builds give
//! bit-identical results. With the `parallel` feature both passes are split over rows with
//! rayon; every output value is computed by the same sequence of floating-point operations
//! whatever the thread count, so the result is bit-identical to the single-threaded one.

use crate::VisionError;
use crate::simd::{Isa, isa, multiversion};
use quarry_core::Plane;

/// Border extrapolation (OpenCV's names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Border {
    /// `gfedcb|abcdefgh|gfedcba` — OpenCV's default `BORDER_REFLECT_101`.
    #[default]
    Reflect101,
    /// `fedcba|abcdefgh|hgfedcb` — `BORDER_REFLECT`.
    Reflect,
    /// `aaaaaa|abcdefgh|hhhhhhh` — `BORDER_REPLICATE`.
    Replicate,
}

impl Border {
    /// Maps an out-of-range coordinate `p` into `0..len` (OpenCV's `borderInterpolate`, including
    /// repeated reflection when the kernel is wider than the image). `len` must be ≥ 1.
    pub fn interpolate(self, p: isize, len: usize) -> usize {
        let n = len as isize;
        if (0..n).contains(&p) {
            return p as usize;
        }
        match self {
            Border::Replicate => {
                if p < 0 {
                    0
                } else {
                    len - 1
                }
            }
            Border::Reflect | Border::Reflect101 => {
                if len == 1 {
                    return 0;
                }
                // the repeated reflection is periodic: period 2(n - 1) for reflect-101 (the edge
                // pixel is not repeated), 2n for reflect. Closed form, so that a kernel much wider
                // than the image costs one step per tap, not one per reflection (`segment
                // --sigma 8000` on a 2-pixel-high image took minutes with the loop).
                let (period, last) = if self == Border::Reflect101 {
                    (2 * (n - 1), 0)
                } else {
                    (2 * n, 1)
                };
                let q = p.rem_euclid(period);
                (if q < n { q } else { period - last - q }) as usize
            }
        }
    }
}

/// A normalised 1-D Gaussian kernel of odd size.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianKernel {
    /// Standard deviation in pixels.
    pub sigma: f64,
    /// The weights `k_{−r} … k_r` (length `2r + 1`), summing to 1.
    pub weights: Vec<f64>,
}

impl GaussianKernel {
    /// Largest supported kernel size (taps); larger sigmas are rejected rather than allocating
    /// unbounded buffers.
    pub const MAX_SIZE: usize = 1 << 16;

    /// Largest sigma whose OpenCV kernel ([`Self::opencv_size`]) fits in [`Self::MAX_SIZE`]
    /// taps: (MAX_SIZE − 2) / 8 = 8191.75 pixels (a kernel of 65 535 taps).
    pub const MAX_SIGMA: f64 = (Self::MAX_SIZE as f64 - 2.0) / 8.0;

    /// OpenCV's kernel size for float images: `round(8σ + 1) | 1` (radius ≈ 4σ).
    pub fn opencv_size(sigma: f64) -> Result<usize, VisionError> {
        check_sigma(sigma)?;
        let s = (sigma * 8.0 + 1.0).round();
        if s > Self::MAX_SIZE as f64 || (s as usize) | 1 > Self::MAX_SIZE {
            return Err(VisionError::SigmaTooLarge {
                sigma,
                max: Self::MAX_SIGMA,
            });
        }
        Ok((s as usize) | 1)
    }

    /// The kernel OpenCV uses for `GaussianBlur(.., (0, 0), sigma)` on float images.
    pub fn new(sigma: f64) -> Result<Self, VisionError> {
        let size = Self::opencv_size(sigma)?;
        Self::with_size(sigma, size)
    }

    /// A kernel with an explicit odd `size` (as `cv2.getGaussianKernel(size, sigma)`).
    pub fn with_size(sigma: f64, size: usize) -> Result<Self, VisionError> {
        check_sigma(sigma)?;
        if size.is_multiple_of(2) || size > Self::MAX_SIZE {
            return Err(quarry_core::CoreError::invalid(
                "kernel size",
                format!("must be odd and at most {}, got {size}", Self::MAX_SIZE),
            )
            .into());
        }
        let r = (size / 2) as f64;
        let scale = -0.5 / (sigma * sigma);
        let mut weights: Vec<f64> = (0..size)
            .map(|i| {
                let x = i as f64 - r;
                // the centre tap is exp(0) = 1 whatever σ: for a σ so small that σ² underflows,
                // `scale` is −∞ and −∞·0 would be NaN (`segment --sigma 1e-200` gave NaN pixels)
                if x == 0.0 { 1.0 } else { (scale * x * x).exp() }
            })
            .collect();
        let sum: f64 = weights.iter().sum();
        for w in &mut weights {
            *w /= sum;
        }
        Ok(Self { sigma, weights })
    }

    /// Radius `r` (the kernel has `2r + 1` taps).
    pub fn radius(&self) -> usize {
        self.weights.len() / 2
    }

    /// Number of taps.
    pub fn size(&self) -> usize {
        self.weights.len()
    }
}

fn check_sigma(sigma: f64) -> Result<(), VisionError> {
    if sigma.is_finite() && sigma > 0.0 {
        Ok(())
    } else {
        Err(VisionError::InvalidSigma(sigma))
    }
}

/// The floating-point sample types the blur runs on.
pub trait BlurSample:
    Copy
    + Send
    + Sync
    + Default
    + std::ops::Add<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::AddAssign
    + 'static
    + sealed::Sealed
{
    /// Conversion of a kernel weight.
    fn from_f64(v: f64) -> Self;
    /// True when finite.
    fn is_finite_sample(self) -> bool;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

impl BlurSample for f32 {
    #[inline]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline]
    fn is_finite_sample(self) -> bool {
        self.is_finite()
    }
}

impl BlurSample for f64 {
    #[inline]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline]
    fn is_finite_sample(self) -> bool {
        self.is_finite()
    }
}

/// Blurs an f64 plane with σ = `sigma` (OpenCV kernel size, reflect-101 border).
///
/// Errors: [`VisionError::InvalidSigma`] unless σ is finite and > 0, [`VisionError::EmptyImage`]
/// for a plane without pixels, [`VisionError::NonFinite`] for NaN/infinite pixels.
pub fn gaussian_blur_f64(src: &Plane<f64>, sigma: f64) -> Result<Plane<f64>, VisionError> {
    let k = GaussianKernel::new(sigma)?;
    gaussian_blur_with(src, &k, Border::Reflect101)
}

/// Blurs an f32 plane with σ = `sigma` (OpenCV kernel size, reflect-101 border); the kernel is
/// rounded to f32 and the sums run in f32, as OpenCV does for `CV_32F`.
///
/// Errors as [`gaussian_blur_f64`].
pub fn gaussian_blur_f32(src: &Plane<f32>, sigma: f64) -> Result<Plane<f32>, VisionError> {
    let k = GaussianKernel::new(sigma)?;
    gaussian_blur_with(src, &k, Border::Reflect101)
}

/// Blurs with an explicit kernel (any odd size) and border mode.
pub fn gaussian_blur_with<T: BlurSample>(
    src: &Plane<T>,
    kernel: &GaussianKernel,
    border: Border,
) -> Result<Plane<T>, VisionError> {
    check_plane(src, "gaussian blur")?;
    let w = src.width as usize;
    let data = blur_rows(
        w,
        src.height as usize,
        |y, row: &mut [T]| row.copy_from_slice(&src.data[y * w..(y + 1) * w]),
        kernel,
        border,
    );
    Ok(Plane {
        width: src.width,
        height: src.height,
        data,
    })
}

/// The separable blur of a `w`×`h` image whose rows are produced on demand by `fill(y, row)`
/// (`row.len() == w`); the caller guarantees finite values and `w, h ≥ 1`. Used to fuse a
/// per-pixel map (the ramp of spec 004) into the horizontal pass without an intermediate image;
/// the output is bit-identical to blurring the materialised image.
pub(crate) fn blur_rows<T: BlurSample>(
    w: usize,
    h: usize,
    fill: impl Fn(usize, &mut [T]) + Sync,
    kernel: &GaussianKernel,
    border: Border,
) -> Vec<T> {
    let r = kernel.radius();
    let k: Vec<T> = kernel.weights[r..]
        .iter()
        .map(|&v| T::from_f64(v))
        .collect();
    #[cfg(feature = "parallel")]
    let streaming = rayon::current_num_threads() == 1;
    #[cfg(not(feature = "parallel"))]
    let streaming = true;
    if streaming {
        return blur_rows_streaming(w, h, &fill, &k, border);
    }
    let mut tmp = vec![T::default(); w * h];
    horizontal_pass(&fill, &mut tmp, w, &k, border);
    let mut out = vec![T::default(); w * h];
    vertical_pass(&tmp, &mut out, w, h, &k, border);
    out
}

/// The single-threaded [`blur_rows`]: the horizontal pass fills a ring of the last
/// `2r + ROWS_PER_TASK` rows, and each band of [`ROWS_PER_TASK`] output rows is summed as soon
/// as its rows are in the ring, walked in strips of [`BLOCK`] columns like
/// [`vertical_band`]. The intermediate image is never allocated and the rows being summed
/// stay in the L2 cache (768 f64 pixels with r = 34: 520 KB, where the intermediate image of
/// 3.5 MB does not fit). Each pixel sees the same operations in the same order as in the
/// two-pass version, so the output is bit-identical (tested).
fn blur_rows_streaming<T: BlurSample>(
    w: usize,
    h: usize,
    fill: &impl Fn(usize, &mut [T]),
    k: &[T],
    border: Border,
) -> Vec<T> {
    let r = k.len() - 1;
    let level = isa();
    // every source row of output row y (reflected or not) lies in [y − r, y + r] ∩ [0, h − 1],
    // so a ring of 2r + ROWS_PER_TASK rows indexed by row % len keeps every row a band needs
    let len = h.min(2 * r + ROWS_PER_TASK);
    // ring rows `ws` apart with an odd number of 64-byte lines between row starts: with a
    // power-of-two-heavy stride (768 f64 = 96 lines) the rows of a strip fall into a few L1
    // sets and evict each other
    let per_line = (64 / std::mem::size_of::<T>()).max(1);
    let lines = w.div_ceil(per_line);
    let ws = (lines | 1) * per_line;
    let mut ring = vec![T::default(); len * ws];
    let mut pad = vec![T::default(); w + 2 * r];
    let mut out = vec![T::default(); w * h];
    let mut filled = 0;
    let mut starts = Vec::with_capacity(ROWS_PER_TASK + 2 * r);
    for (band, out_band) in out.chunks_mut(w * ROWS_PER_TASK).enumerate() {
        let y0 = band * ROWS_PER_TASK;
        let rows = out_band.len() / w;
        let last = (y0 + rows - 1 + r).min(h - 1);
        while filled <= last {
            padded_row(fill, filled, &mut pad, r, border);
            let slot = (filled % len) * ws;
            blur_row(level, &pad, &mut ring[slot..slot + w], k);
            filled += 1;
        }
        starts.clear();
        starts.extend(
            (0..rows + 2 * r)
                .map(|i| (border.interpolate((y0 + i) as isize - r as isize, h) % len) * ws),
        );
        ring_band(level, &ring, out_band, w, &starts, k);
    }
    out
}

multiversion!(avx512, avx2:
    /// A band of output rows of [`blur_rows_streaming`] (dispatching like [`blur_row`]).
    #[inline]
    fn ring_band<[T: BlurSample]> => ring_band_body(
        src: &[T],
        out: &mut [T],
        w: usize,
        starts: &[usize],
        k: &[T],
    )
);

/// A band of rows of the vertical pass, `out` holding whole rows: `starts[i]` is where the
/// source row `y0 − r + i` starts in `src` (a ring's slot, or the reflected row of a whole
/// image), and `out[x] = k0 src[c][x] + Σ_j k_j (src[u_j][x] + src[d_j][x])` in that order (as
/// [`blur_row_body`]). The band is walked in strips of [`BLOCK`] columns, each strip from the
/// band's first row to its last, so that the `2r + rows` source rows of a strip stay in the L1
/// cache while they are reused; the accumulators of one output block stay in registers. The
/// per-pixel operation sequence does not depend on the walk, so neither does the result.
// Inlined into the builds of `multiversion!` so that the loop is compiled for each ISA there.
#[allow(clippy::inline_always)]
#[inline(always)]
fn ring_band_body<T: BlurSample>(src: &[T], out: &mut [T], w: usize, starts: &[usize], k: &[T]) {
    let r = k.len() - 1;
    let k0 = k[0];
    let full = w - w % BLOCK;
    for x0 in (0..full).step_by(BLOCK) {
        for (i, out_row) in out.chunks_exact_mut(w).enumerate() {
            let c0 = starts[i + r];
            let mut acc = [T::default(); BLOCK];
            for (a, &v) in acc.iter_mut().zip(&src[c0 + x0..c0 + x0 + BLOCK]) {
                *a = k0 * v;
            }
            for (j, &kj) in k.iter().enumerate().skip(1) {
                let (u0, d0) = (starts[i + r - j], starts[i + r + j]);
                let up = &src[u0 + x0..u0 + x0 + BLOCK];
                let down = &src[d0 + x0..d0 + x0 + BLOCK];
                for ((a, &u), &v) in acc.iter_mut().zip(up).zip(down) {
                    *a += kj * (u + v);
                }
            }
            out_row[x0..x0 + BLOCK].copy_from_slice(&acc);
        }
    }
    if full == w {
        return;
    }
    for (i, out_row) in out.chunks_exact_mut(w).enumerate() {
        let c0 = starts[i + r];
        let tail = &mut out_row[full..];
        for (o, &c) in tail.iter_mut().zip(&src[c0 + full..c0 + w]) {
            *o = k0 * c;
        }
        for (j, &kj) in k.iter().enumerate().skip(1) {
            let (u0, d0) = (starts[i + r - j], starts[i + r + j]);
            let up = &src[u0 + full..u0 + w];
            let down = &src[d0 + full..d0 + w];
            for ((o, &a), &b) in tail.iter_mut().zip(up).zip(down) {
                *o += kj * (a + b);
            }
        }
    }
}

pub(crate) fn check_plane<T: BlurSample>(
    src: &Plane<T>,
    what: &'static str,
) -> Result<(), VisionError> {
    if src.width == 0 || src.height == 0 || src.data.is_empty() {
        return Err(VisionError::EmptyImage {
            what,
            width: src.width,
            height: src.height,
            min: 1,
        });
    }
    if src.data.len() != src.width as usize * src.height as usize {
        return Err(quarry_core::CoreError::DimensionMismatch {
            what: "plane data length (width * height)",
            expected: src.width as usize * src.height as usize,
            got: src.data.len(),
        }
        .into());
    }
    if !src.data.iter().all(|v| v.is_finite_sample()) {
        return Err(VisionError::NonFinite(what));
    }
    Ok(())
}

/// Rows per parallel task (large enough to amortise scheduling, small enough to balance), and
/// the band of the vertical pass (whose strips of `2r + 16` source rows stay in L1).
const ROWS_PER_TASK: usize = 16;

/// Source row `y` (from `fill`) in the middle of `pad` (length `w + 2r`) with its `r` reflected
/// values at each end: the input of [`blur_row`].
fn padded_row<T: BlurSample>(
    fill: &impl Fn(usize, &mut [T]),
    y: usize,
    pad: &mut [T],
    r: usize,
    border: Border,
) {
    let w = pad.len() - 2 * r;
    fill(y, &mut pad[r..r + w]);
    for i in (0..r).chain(r + w..w + 2 * r) {
        pad[i] = pad[r + border.interpolate(i as isize - r as isize, w)];
    }
}

fn horizontal_pass<T: BlurSample>(
    fill: &(impl Fn(usize, &mut [T]) + Sync),
    dst: &mut [T],
    w: usize,
    k: &[T],
    border: Border,
) {
    let r = k.len() - 1;
    let level = isa();
    // the source row goes into the middle of `pad`, the reflected borders around it
    let row_fn = |y: usize, dst_row: &mut [T], pad: &mut Vec<T>| {
        pad.resize(w + 2 * r, T::default());
        padded_row(fill, y, pad, r, border);
        blur_row(level, pad, dst_row, k);
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        dst.par_chunks_mut(w * ROWS_PER_TASK)
            .enumerate()
            .for_each(|(band, d)| {
                let mut pad = Vec::with_capacity(w + 2 * r);
                for (i, row) in d.chunks_mut(w).enumerate() {
                    row_fn(band * ROWS_PER_TASK + i, row, &mut pad);
                }
            });
    }
    #[cfg(not(feature = "parallel"))]
    {
        let mut pad = Vec::with_capacity(w + 2 * r);
        for (y, row) in dst.chunks_mut(w).enumerate() {
            row_fn(y, row, &mut pad);
        }
    }
}

multiversion!(avx512, avx2:
    /// One horizontal output row, also compiled for AVX2 and AVX-512F and dispatched at run time
    /// ([`crate::simd`]). Without FMA contraction (Rust never fuses `a * b + c`) every build
    /// performs exactly the same IEEE operations per pixel, so results are bit-identical on every
    /// x86-64 CPU (tested).
    #[inline]
    fn blur_row<[T: BlurSample]> => blur_row_body(pad: &[T], out: &mut [T], k: &[T])
);

/// Pixels per register block: the accumulators of one block stay in registers over all taps
/// (8 AVX2 registers for f64, 4 for f32).
const BLOCK: usize = 32;

/// `out[x] = k0 pad[x + r] + Σ_j k_j (pad[x + r − j] + pad[x + r + j])`, the sum taken in this
/// order (j = 1, 2, …) for every pixel. Blocks of [`BLOCK`] pixels keep their accumulators in
/// registers while the taps are walked; the per-pixel operation sequence is the same as a
/// taps-outer loop, so the result does not depend on the blocking.
// Inlined into the builds of `multiversion!` so that the loop is compiled for each ISA there.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn blur_row_body<T: BlurSample>(pad: &[T], out: &mut [T], k: &[T]) {
    let r = k.len() - 1;
    let w = out.len();
    let k0 = k[0];
    let full = w - w % BLOCK;
    for x0 in (0..full).step_by(BLOCK) {
        let mut acc = [T::default(); BLOCK];
        let c = &pad[r + x0..r + x0 + BLOCK];
        for (a, &v) in acc.iter_mut().zip(c) {
            *a = k0 * v;
        }
        for (j, &kj) in k.iter().enumerate().skip(1) {
            let left = &pad[r + x0 - j..r + x0 - j + BLOCK];
            let right = &pad[r + x0 + j..r + x0 + j + BLOCK];
            for ((a, &u), &v) in acc.iter_mut().zip(left).zip(right) {
                *a += kj * (u + v);
            }
        }
        out[x0..x0 + BLOCK].copy_from_slice(&acc);
    }
    let tail = &mut out[full..];
    let centre = &pad[r + full..r + w];
    for (o, &c) in tail.iter_mut().zip(centre) {
        *o = k0 * c;
    }
    for (j, &kj) in k.iter().enumerate().skip(1) {
        let left = &pad[r + full - j..r + w - j];
        let right = &pad[r + full + j..r + w + j];
        for ((o, &a), &b) in tail.iter_mut().zip(left).zip(right) {
            *o += kj * (a + b);
        }
    }
}

fn vertical_pass<T: BlurSample>(
    src: &[T],
    dst: &mut [T],
    w: usize,
    h: usize,
    k: &[T],
    border: Border,
) {
    let level = isa();
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        dst.par_chunks_mut(w * ROWS_PER_TASK)
            .enumerate()
            .for_each(|(band, d)| {
                vertical_band(level, src, d, w, h, band * ROWS_PER_TASK, k, border);
            });
    }
    #[cfg(not(feature = "parallel"))]
    {
        for (band, d) in dst.chunks_mut(w * ROWS_PER_TASK).enumerate() {
            vertical_band(level, src, d, w, h, band * ROWS_PER_TASK, k, border);
        }
    }
}

/// Rows `y0..` of the vertical pass, `out` holding whole rows:
/// `out[x] = k0 src[y][x] + Σ_j k_j (src[y − j][x] + src[y + j][x])` (same order of operations
/// as [`blur_row_body`]), summed by [`ring_band`] over the band's reflected row starts.
#[allow(clippy::too_many_arguments)]
fn vertical_band<T: BlurSample>(
    level: Isa,
    src: &[T],
    out: &mut [T],
    w: usize,
    h: usize,
    y0: usize,
    k: &[T],
    border: Border,
) {
    let r = k.len() - 1;
    let rows = out.len() / w;
    // row starts of src rows y0 − r ..= y0 + rows − 1 + r (reflected at the borders)
    let starts: Vec<usize> = (0..rows + 2 * r)
        .map(|i| border.interpolate((y0 + i) as isize - r as isize, h) * w)
        .collect();
    ring_band(level, src, out, w, &starts, k);
}

/// Blurs a 1-D signal with `kernel` (used for the exact blur of the separable ramp).
pub fn gaussian_blur_1d(
    signal: &[f64],
    kernel: &GaussianKernel,
    border: Border,
) -> Result<Vec<f64>, VisionError> {
    if signal.is_empty() {
        return Err(quarry_core::CoreError::Empty {
            what: "1-D blur signal",
        }
        .into());
    }
    if !signal.iter().all(|v| v.is_finite()) {
        return Err(VisionError::NonFinite("1-D blur signal"));
    }
    let n = signal.len();
    let r = kernel.radius();
    let k = &kernel.weights[r..];
    let pad: Vec<f64> = (0..n + 2 * r)
        .map(|i| signal[border.interpolate(i as isize - r as isize, n)])
        .collect();
    let mut out = vec![0.0; n];
    blur_row(isa(), &pad, &mut out, k);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row kernels give the same bits in every build the CPU supports (baseline, AVX2,
    /// AVX-512F): no FMA contraction, the same operation order per pixel.
    #[test]
    fn every_isa_build_gives_the_same_bits() {
        fn check<T: BlurSample + std::fmt::Debug>(to: impl Fn(f64) -> T, bits: impl Fn(T) -> u64) {
            let levels = crate::simd::Isa::all_supported();
            let mut seed = 99u32;
            let mut next = move || {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                f64::from(seed >> 8) / 256.0
            };
            for &(w, h) in &[
                (1usize, 1usize),
                (7, 3),
                (31, 9),
                (32, 4),
                (33, 40),
                (100, 70),
            ] {
                let src: Vec<T> = (0..w * h).map(|_| to(next())).collect();
                for sigma in [0.8, 2.0, 8.0] {
                    let kern = GaussianKernel::new(sigma).unwrap();
                    let r = kern.radius();
                    let k: Vec<T> = kern.weights[r..].iter().map(|&v| T::from_f64(v)).collect();
                    let pad: Vec<T> = (0..w + 2 * r).map(|_| to(next())).collect();
                    let run = |level| {
                        let mut row = vec![T::default(); w];
                        blur_row(level, &pad, &mut row, &k);
                        let mut col = Vec::new();
                        for band in [1, 5, 16, h] {
                            for y0 in (0..h).step_by(band) {
                                let n = band.min(h - y0);
                                let mut out = vec![T::default(); w * n];
                                vertical_band(
                                    level,
                                    &src,
                                    &mut out,
                                    w,
                                    h,
                                    y0,
                                    &k,
                                    Border::Reflect101,
                                );
                                col.extend(out);
                            }
                        }
                        // every band size gives the per-pixel sum in the documented order
                        let bb = Border::Reflect101;
                        let at = |y: isize, x: usize| src[bb.interpolate(y, h) * w + x];
                        for (i, &v) in col.iter().enumerate() {
                            let (y, x) = ((i / w) % h, i % w);
                            let mut want = k[0] * src[y * w + x];
                            for (j, &kj) in k.iter().enumerate().skip(1) {
                                let j = j as isize;
                                want += kj * (at(y as isize - j, x) + at(y as isize + j, x));
                            }
                            assert_eq!(bits(v), bits(want), "{w}x{h} sigma {sigma} at {x},{y}");
                        }
                        row.into_iter().chain(col).map(&bits).collect::<Vec<u64>>()
                    };
                    let want = run(levels[0]);
                    for &level in &levels[1..] {
                        assert_eq!(run(level), want, "{w}x{h} sigma {sigma} {level:?}");
                    }
                }
            }
        }
        check(|v| v, f64::to_bits);
        check(|v| v as f32, |v: f32| u64::from(v.to_bits()));
    }

    #[test]
    fn opencv_sizes() {
        assert_eq!(GaussianKernel::opencv_size(8.0).unwrap(), 65);
        assert_eq!(GaussianKernel::opencv_size(5.0).unwrap(), 41);
        assert_eq!(GaussianKernel::opencv_size(1.6).unwrap(), 15);
        assert_eq!(GaussianKernel::opencv_size(0.5).unwrap(), 5);
        assert!(GaussianKernel::opencv_size(0.0).is_err());
        assert!(GaussianKernel::opencv_size(-1.0).is_err());
        assert!(GaussianKernel::opencv_size(f64::NAN).is_err());
        assert!(GaussianKernel::opencv_size(1e9).is_err());
    }

    #[test]
    fn tiny_sigma_is_the_identity_not_nan() {
        for sigma in [1e-200, 1e-160, 1e-30] {
            let k = GaussianKernel::new(sigma).unwrap();
            assert_eq!(k.weights, vec![1.0], "{sigma}");
            let k = GaussianKernel::with_size(sigma, 5).unwrap();
            assert_eq!(k.weights, vec![0.0, 0.0, 1.0, 0.0, 0.0], "{sigma}");
        }
    }

    #[test]
    fn kernel_sums_to_one() {
        for s in [0.3, 1.0, 1.6, 5.0, 8.0, 20.0] {
            let k = GaussianKernel::new(s).unwrap();
            let sum: f64 = k.weights.iter().sum();
            assert!((sum - 1.0).abs() < 1e-12, "sigma {s}: {sum}");
            // symmetric and peaked at the centre
            let r = k.radius();
            for j in 0..r {
                assert_eq!(k.weights[j], k.weights[2 * r - j]);
                assert!(k.weights[j] < k.weights[j + 1]);
            }
        }
    }

    #[test]
    fn border_interpolation_matches_opencv() {
        // cv2.borderInterpolate values
        let b = Border::Reflect101;
        assert_eq!(b.interpolate(-1, 5), 1);
        assert_eq!(b.interpolate(-2, 5), 2);
        assert_eq!(b.interpolate(5, 5), 3);
        assert_eq!(b.interpolate(6, 5), 2);
        assert_eq!(b.interpolate(-7, 5), 1); // repeated reflection
        assert_eq!(b.interpolate(3, 1), 0);
        let b = Border::Reflect;
        assert_eq!(b.interpolate(-1, 5), 0);
        assert_eq!(b.interpolate(5, 5), 4);
        assert_eq!(b.interpolate(-12, 5), 1);
        assert_eq!(Border::Replicate.interpolate(-3, 5), 0);
        assert_eq!(Border::Replicate.interpolate(9, 5), 4);
        for len in 1..6usize {
            for p in -40..40 {
                for b in [Border::Reflect101, Border::Reflect, Border::Replicate] {
                    assert!(b.interpolate(p, len) < len);
                }
            }
        }
    }

    /// OpenCV's `borderInterpolate` loop, reflection by reflection.
    fn reflect_loop(p: isize, len: usize, delta: isize) -> usize {
        let n = len as isize;
        let mut p = p;
        while !(0..n).contains(&p) {
            p = if p < 0 {
                -p - 1 + delta
            } else {
                n - 1 - (p - n) - delta
            };
        }
        p as usize
    }

    proptest::proptest! {
        #[test]
        fn closed_form_reflection_equals_opencvs_loop(p in -5000isize..5000, len in 2usize..40) {
            proptest::prop_assert_eq!(Border::Reflect101.interpolate(p, len), reflect_loop(p, len, 1));
            proptest::prop_assert_eq!(Border::Reflect.interpolate(p, len), reflect_loop(p, len, 0));
        }
    }

    /// The two-pass path of [`blur_rows`] (what more than one rayon thread runs).
    fn two_pass<T: BlurSample>(src: &[T], w: usize, h: usize, k: &[T], border: Border) -> Vec<T> {
        let fill = |y: usize, row: &mut [T]| row.copy_from_slice(&src[y * w..(y + 1) * w]);
        let mut tmp = vec![T::default(); w * h];
        horizontal_pass(&fill, &mut tmp, w, k, border);
        let mut out = vec![T::default(); w * h];
        vertical_pass(&tmp, &mut out, w, h, k, border);
        out
    }

    proptest::proptest! {
        /// The single-threaded ring path gives the two-pass path's bits for every border, any
        /// image size (below and above the ring's 2r + 16 rows, below and above a block's 32
        /// columns) and any kernel, also one much wider than the image.
        #[test]
        fn the_streaming_blur_gives_the_two_pass_bits(
            w in 1usize..80,
            h in 1usize..120,
            sigma in 0.3f64..12.0,
            border in 0usize..3,
            seed in 0u32..1000,
        ) {
            let border = [Border::Reflect101, Border::Reflect, Border::Replicate][border];
            let kern = GaussianKernel::new(sigma).unwrap();
            let r = kern.radius();
            let mut state = seed;
            let src: Vec<f64> = (0..w * h)
                .map(|_| {
                    state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    f64::from(state >> 8) / 65536.0
                })
                .collect();
            let k64: Vec<f64> = kern.weights[r..].to_vec();
            let fill = |y: usize, row: &mut [f64]| row.copy_from_slice(&src[y * w..(y + 1) * w]);
            let a = blur_rows_streaming(w, h, &fill, &k64, border);
            let b = two_pass(&src, w, h, &k64, border);
            proptest::prop_assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
            let src32: Vec<f32> = src.iter().map(|&v| v as f32).collect();
            let k32: Vec<f32> = k64.iter().map(|&v| v as f32).collect();
            let fill = |y: usize, row: &mut [f32]| row.copy_from_slice(&src32[y * w..(y + 1) * w]);
            let a = blur_rows_streaming(w, h, &fill, &k32, border);
            let b = two_pass(&src32, w, h, &k32, border);
            proptest::prop_assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }

    #[test]
    fn a_kernel_much_wider_than_the_image_is_cheap_and_a_too_wide_one_is_named() {
        // sigma 8000 on a 2-pixel-high image: 64 001 taps, each reflected in one step
        let img = Plane::from_fn(40, 2, |x, y| (x + 3 * y) as f64);
        let out = gaussian_blur_f64(&img, 8000.0).unwrap();
        let mean = img.data.iter().sum::<f64>() / 80.0;
        assert!(
            out.data.iter().all(|v| (v - mean).abs() < 1.0),
            "{:?}",
            out.data
        );
        match GaussianKernel::new(1e6) {
            Err(VisionError::SigmaTooLarge { max, .. }) => assert_eq!(max, 8191.75),
            other => panic!("{other:?}"),
        }
        assert!(GaussianKernel::new(GaussianKernel::MAX_SIGMA).is_ok());
    }

    #[test]
    fn constant_stays_constant() {
        let p = Plane::new(37, 11, 123.25f64);
        let b = gaussian_blur_f64(&p, 8.0).unwrap();
        for v in &b.data {
            assert!((v - 123.25).abs() < 1e-12);
        }
        let p = Plane::new(5, 3, 7.5f32);
        let b = gaussian_blur_f32(&p, 2.0).unwrap();
        for v in &b.data {
            assert!((v - 7.5).abs() < 1e-5);
        }
    }

    #[test]
    fn linear_ramp_unchanged_in_interior() {
        let p = Plane::from_fn(120, 90, |x, y| {
            0.37 * f64::from(x) - 1.1 * f64::from(y) + 3.0
        });
        let b = gaussian_blur_f64(&p, 4.0).unwrap();
        let r = GaussianKernel::new(4.0).unwrap().radius() as u32;
        let mut checked = 0;
        for y in r..90 - r {
            for x in r..120 - r {
                let d = b.get(x, y).unwrap() - p.get(x, y).unwrap();
                assert!(d.abs() < 1e-9, "({x},{y}) {d}");
                checked += 1;
            }
        }
        assert!(checked > 1000);
    }

    #[test]
    fn impulse_gives_kernel() {
        let mut p = Plane::new(41, 41, 0.0f64);
        p.set(20, 20, 1.0);
        let b = gaussian_blur_f64(&p, 2.0).unwrap();
        let k = GaussianKernel::new(2.0).unwrap();
        let r = k.radius();
        for dy in 0..k.size() {
            for dx in 0..k.size() {
                let v = b.get((20 + dx - r) as u32, (20 + dy - r) as u32).unwrap();
                assert!((v - k.weights[dx] * k.weights[dy]).abs() < 1e-15);
            }
        }
    }

    /// Straightforward per-pixel form of the two passes (the operation order the blocked loops
    /// must keep): results must be bit-identical.
    fn naive<T: BlurSample>(src: &Plane<T>, kernel: &GaussianKernel, border: Border) -> Vec<T> {
        let (w, h) = (src.width as usize, src.height as usize);
        let r = kernel.radius();
        let k: Vec<T> = kernel.weights[r..]
            .iter()
            .map(|&v| T::from_f64(v))
            .collect();
        let at = |d: &[T], x: isize, y: isize| {
            d[border.interpolate(y, h) * w + border.interpolate(x, w)]
        };
        let mut tmp = vec![T::default(); w * h];
        for y in 0..h as isize {
            for x in 0..w as isize {
                let mut o = k[0] * at(&src.data, x, y);
                for j in 1..=r as isize {
                    o += k[j as usize] * (at(&src.data, x - j, y) + at(&src.data, x + j, y));
                }
                tmp[y as usize * w + x as usize] = o;
            }
        }
        let mut out = vec![T::default(); w * h];
        for y in 0..h as isize {
            for x in 0..w as isize {
                let mut o = k[0] * at(&tmp, x, y);
                for j in 1..=r as isize {
                    o += k[j as usize] * (at(&tmp, x, y - j) + at(&tmp, x, y + j));
                }
                out[y as usize * w + x as usize] = o;
            }
        }
        out
    }

    #[test]
    fn blocked_passes_are_bit_identical_to_per_pixel_sums() {
        use quarry_core::rng::RngCore;
        let mut rng = quarry_core::rng::seeded(5);
        for (w, h, sigma) in [
            (1, 1, 1.0),
            (31, 7, 2.0),
            (32, 33, 1.3),
            (77, 40, 8.0),
            (100, 3, 0.7),
            (5, 70, 8.0),
        ] {
            let p = Plane::from_fn(w, h, |_, _| f64::from(rng.next_u32() % 256) + 0.1);
            for border in [Border::Reflect101, Border::Reflect, Border::Replicate] {
                let k = GaussianKernel::new(sigma).unwrap();
                let a = gaussian_blur_with(&p, &k, border).unwrap();
                let b = naive(&p, &k, border);
                assert!(
                    a.data
                        .iter()
                        .zip(&b)
                        .all(|(x, y)| x.to_bits() == y.to_bits()),
                    "f64 {w}x{h} {sigma} {border:?}"
                );
                let p32 = p.map(|&v| v as f32);
                let a = gaussian_blur_with(&p32, &k, border).unwrap();
                let b = naive(&p32, &k, border);
                assert!(
                    a.data
                        .iter()
                        .zip(&b)
                        .all(|(x, y)| x.to_bits() == y.to_bits()),
                    "f32 {w}x{h} {sigma} {border:?}"
                );
            }
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let empty = Plane::<f64>::new(0, 5, 0.0);
        assert!(matches!(
            gaussian_blur_f64(&empty, 1.0),
            Err(VisionError::EmptyImage { .. })
        ));
        let mut p = Plane::new(4, 4, 1.0f32);
        assert!(matches!(
            gaussian_blur_f32(&p, 0.0),
            Err(VisionError::InvalidSigma(_))
        ));
        assert!(matches!(
            gaussian_blur_f32(&p, f64::INFINITY),
            Err(VisionError::InvalidSigma(_))
        ));
        p.set(1, 2, f32::NAN);
        assert!(matches!(
            gaussian_blur_f32(&p, 1.0),
            Err(VisionError::NonFinite(_))
        ));
        let one = Plane::new(1, 1, 3.0f64);
        assert!((gaussian_blur_f64(&one, 3.0).unwrap().data[0] - 3.0).abs() < 1e-12);
        assert!(GaussianKernel::with_size(1.0, 4).is_err());
        let k = GaussianKernel::new(1.0).unwrap();
        assert!(gaussian_blur_1d(&[], &k, Border::Reflect101).is_err());
        let b = gaussian_blur_1d(&[1.0, 2.0, 3.0, 4.0], &k, Border::Replicate).unwrap();
        assert!(b[0] > 1.0 && b[0] < 2.0 && b[3] < 4.0 && b[3] > 3.0);
    }
}
