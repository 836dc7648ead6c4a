//! SIFT keypoints and descriptors (Lowe 2004), following OpenCV's `cv::SIFT` wherever Lowe
//! leaves a choice (spec 004 §4), so that keypoints, descriptors and descriptor distances can be
//! compared one to one with OpenCV's.
//!
//! ```
//! use quarry_core::{FeatureExtractor, Plane};
//! use quarry_vision::sift::{Sift, SiftParams};
//!
//! // A dark disc on a bright background: a blob SIFT finds at the disc's scale.
//! let img = Plane::from_fn(64, 64, |x, y| {
//!     let (dx, dy) = (x as f32 - 31.5, y as f32 - 31.5);
//!     if dx * dx + dy * dy < 36.0 { 40u8 } else { 200u8 }
//! });
//! let sift = Sift::new(SiftParams::default()).unwrap();
//! let (kps, desc) = sift.detect_and_compute(&img).unwrap();
//! assert_eq!(kps.len(), desc.len());
//! assert!(kps.iter().any(|k| (k.x - 31.5).abs() < 1.0 && (k.y - 31.5).abs() < 1.0));
//! ```
//!
//! # Choices (where Lowe leaves one, OpenCV's; where the spec resolves one, the spec's)
//! - Intensities are kept in 0..255 (as OpenCV) and derivatives are scaled by 1/255 inside the
//!   refinement, so the contrast threshold `0.04 / s` applies to intensities in [0, 1].
//! - The scale space uses the Gaussian blur of [`crate::blur::gaussian_blur_f32`] (OpenCV's
//!   kernel-size rule, reflect-101; SIFT runs its own register-blocked build of it, bit-identical
//!   to that function), bilinear ×2 up-sampling with pixel-centre alignment, and decimation by
//!   taking every second pixel. DoG images are not stored: each DoG value is the subtraction
//!   `G[l + 1] − G[l]` done where it is needed.
//! - Keypoint coordinates follow OpenCV exactly: `x = (column + δx)·2^octave` in octave pixels
//!   mapped to input pixels (for the up-sampled octave this is OpenCV's `KeyPoint.pt`, which
//!   carries a 0.25 px offset with respect to pixel centres).
//! - Gradient orientations use OpenCV's polynomial `fastAtan2` (error below 0.01°) so that
//!   histogram bins agree with OpenCV's.
//! - Keypoints are returned sorted by (x, y, σ, angle, response), exact duplicates removed.
//! - Parallelism (feature `parallel`): the Gaussian blurs are row-parallel, and extremum rows,
//!   candidates and descriptors are processed in parallel with order-preserving collection;
//!   results are bit-identical for any number of threads.
//! - Speed (issue 6): the hot loops (blur, extremum scan, orientation and descriptor
//!   histograms) are compiled for baseline x86-64, AVX2 and AVX-512F and chosen at run time;
//!   without FMA contraction all builds perform the same IEEE operations, so the output does
//!   not depend on the CPU. Histogram samples are gathered per window row as contiguous runs and
//!   accumulated in OpenCV's order, so every sum is the one of the plain scalar loop.

use crate::VisionError;
use quarry_core::{
    CoreError, DescriptorExtractor, FeatureDetector, FeatureExtractor, Keypoint, Plane,
};
use serde::{Deserialize, Serialize};

#[cfg(feature = "parallel")]
use rayon::prelude::*;

mod fast;
use fast::{isa, multiversion};

/// A SIFT descriptor: 4×4 cells × 8 orientation bins, element `(row·4 + col)·8 + bin`
/// (OpenCV's layout), L2 norm ≈ 512.
pub type SiftDescriptor = [u8; 128];

/// Length of a SIFT descriptor.
pub const DESCRIPTOR_LEN: usize = 128;

/// Largest accepted image, in pixels (16 Mpx, e.g. 4096×4096). With the up-sampled first
/// octave the scale space takes about 150 bytes per input pixel (about 2.5 GB at the limit).
pub const MAX_PIXELS: u64 = 1 << 24;

/// Smallest accepted image side in pixels. The 5-px border ignored in every octave leaves no
/// room for extrema on smaller images.
pub const MIN_SIDE: u32 = 16;

const IMG_BORDER: usize = 5;
const MAX_INTERP_STEPS: usize = 5;
const ORI_HIST_BINS: usize = 36;
const ORI_SIG_FCTR: f32 = 1.5;
const ORI_RADIUS: f32 = 4.5;
const ORI_PEAK_RATIO: f32 = 0.8;
const DESCR_WIDTH: usize = 4;
const DESCR_HIST_BINS: usize = 8;
const DESCR_SCL_FCTR: f32 = 3.0;
const DESCR_MAG_THR: f32 = 0.2;
const INT_DESCR_FCTR: f32 = 512.0;

/// SIFT parameters. `Default` is OpenCV's `SIFT_create()` (spec 004 §4.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SiftParams {
    /// Intervals per octave s (`nOctaveLayers`); 3.
    pub n_octave_layers: u32,
    /// Base scale σ₀ of each octave; 1.6.
    pub sigma: f64,
    /// Blur assumed already present in the input σ_in; 0.5.
    pub input_blur: f64,
    /// Contrast threshold T_c (for intensities in [0, 1]); applied as T_c / s. 0.04.
    pub contrast_threshold: f64,
    /// Edge threshold r (ratio of principal curvatures); 10.
    pub edge_threshold: f64,
    /// Up-sample the input ×2 for a first octave −1; true.
    pub upsample: bool,
    /// Keep only the `max_features` strongest keypoints (by response); 0 keeps all.
    pub max_features: usize,
}

impl Default for SiftParams {
    fn default() -> Self {
        Self {
            n_octave_layers: 3,
            sigma: 1.6,
            input_blur: 0.5,
            contrast_threshold: 0.04,
            edge_threshold: 10.0,
            upsample: true,
            max_features: 0,
        }
    }
}

impl SiftParams {
    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), VisionError> {
        if !(1..=16).contains(&self.n_octave_layers) {
            return Err(CoreError::invalid("n_octave_layers", "must be in 1..=16").into());
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0 && self.sigma < 64.0) {
            return Err(CoreError::invalid("sigma", "must be finite and in (0, 64)").into());
        }
        if !(self.input_blur.is_finite() && self.input_blur >= 0.0) {
            return Err(CoreError::invalid("input_blur", "must be finite and >= 0").into());
        }
        if !(self.contrast_threshold.is_finite() && self.contrast_threshold >= 0.0) {
            return Err(CoreError::invalid("contrast_threshold", "must be finite and >= 0").into());
        }
        if !(self.edge_threshold.is_finite() && self.edge_threshold > 0.0) {
            return Err(CoreError::invalid("edge_threshold", "must be finite and > 0").into());
        }
        Ok(())
    }
}

/// The SIFT detector and descriptor extractor.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Sift {
    params: SiftParams,
}

/// One octave of the scale space: `s + 3` Gaussian images. The `s + 2` DoG images are not
/// stored: every DoG value is computed where it is used as `G[l + 1] − G[l]` (the same single
/// subtraction, so the values are those of stored DoG images), which saves allocating and
/// writing 5 images per octave.
#[derive(Debug, Clone)]
struct Octave {
    gauss: Vec<Plane<f32>>,
}

/// The Gaussian and difference-of-Gaussian pyramids of one image.
#[derive(Debug, Clone)]
pub struct ScaleSpace {
    octaves: Vec<Octave>,
    first_octave: i32,
    layers: usize,
}

impl ScaleSpace {
    /// Number of octaves.
    pub fn n_octaves(&self) -> usize {
        self.octaves.len()
    }

    /// Index of the first octave (−1 when up-sampled).
    pub fn first_octave(&self) -> i32 {
        self.first_octave
    }

    /// Gaussian image `layer` (0..s+3) of `octave` (counted from [`Self::first_octave`]).
    pub fn gaussian(&self, octave: i32, layer: usize) -> Option<&Plane<f32>> {
        let o = usize::try_from(octave - self.first_octave).ok()?;
        self.octaves.get(o)?.gauss.get(layer)
    }

    /// DoG image `layer` (0..s+2) of `octave`: `G[layer + 1] − G[layer]` (computed on request;
    /// the scale space does not store DoG images).
    pub fn dog(&self, octave: i32, layer: usize) -> Option<Plane<f32>> {
        let o = usize::try_from(octave - self.first_octave).ok()?;
        let g = &self.octaves.get(o)?.gauss;
        Some(sub_planes(g.get(layer + 1)?, g.get(layer)?))
    }
}

/// Maps a quarry-vision error onto the shared kinds returned by the core traits.
fn to_core(e: VisionError) -> CoreError {
    match e {
        VisionError::Core(c) => c,
        VisionError::NonFinite(what) => CoreError::NonFinite { what },
        other => CoreError::invalid("image", other.to_string()),
    }
}

impl Sift {
    /// A SIFT with checked parameters.
    pub fn new(params: SiftParams) -> Result<Self, VisionError> {
        params.validate()?;
        Ok(Self { params })
    }

    /// The parameters.
    pub fn params(&self) -> &SiftParams {
        &self.params
    }

    /// Checks the size of an input image.
    fn check_size(width: u32, height: u32) -> Result<(), VisionError> {
        if width < MIN_SIDE || height < MIN_SIDE {
            return Err(VisionError::EmptyImage {
                what: "SIFT",
                width,
                height,
                min: MIN_SIDE,
            });
        }
        let n = u64::from(width) * u64::from(height);
        if n > MAX_PIXELS {
            return Err(VisionError::TooLarge {
                what: "SIFT",
                width,
                height,
                limit: MAX_PIXELS,
            });
        }
        Ok(())
    }

    /// Converts an 8-bit image to the 0..255 float image SIFT works on.
    fn to_f32(img: &Plane<u8>) -> Result<Plane<f32>, VisionError> {
        Self::check_size(img.width, img.height)?;
        Ok(img.map(|&v| f32::from(v)))
    }

    /// Builds the scale space of a float image with intensities in 0..255 (NaN or infinite pixels
    /// are an error).
    pub fn scale_space(&self, img: &Plane<f32>) -> Result<ScaleSpace, VisionError> {
        Self::check_size(img.width, img.height)?;
        if img.data.len() != img.width as usize * img.height as usize {
            return Err(CoreError::DimensionMismatch {
                what: "SIFT image data length (width * height)",
                expected: img.width as usize * img.height as usize,
                got: img.data.len(),
            }
            .into());
        }
        if !img.data.iter().all(|v| v.is_finite()) {
            return Err(VisionError::NonFinite("SIFT input image"));
        }
        build_scale_space(img, &self.params)
    }

    /// Detects keypoints in an 8-bit grey image.
    pub fn detect_keypoints(&self, img: &Plane<u8>) -> Result<Vec<Keypoint>, VisionError> {
        let ss = self.scale_space(&Self::to_f32(img)?)?;
        Ok(self.detect_in(&ss))
    }

    /// Detects keypoints and computes their descriptors in an 8-bit grey image, building the
    /// scale space once.
    pub fn extract(
        &self,
        img: &Plane<u8>,
    ) -> Result<(Vec<Keypoint>, Vec<SiftDescriptor>), VisionError> {
        self.extract_f32(&Self::to_f32(img)?)
    }

    /// [`Self::extract`] on a float image with intensities in 0..255.
    pub fn extract_f32(
        &self,
        img: &Plane<f32>,
    ) -> Result<(Vec<Keypoint>, Vec<SiftDescriptor>), VisionError> {
        let ss = self.scale_space(img)?;
        let kps = self.detect_in(&ss);
        let desc = self.describe_in(&ss, &kps)?;
        Ok((kps, desc.iter().map(quantize).collect()))
    }

    /// Keypoints of a scale space.
    pub fn detect_in(&self, ss: &ScaleSpace) -> Vec<Keypoint> {
        let mut kps = find_keypoints(ss, &self.params);
        sort_dedup(&mut kps);
        if self.params.max_features > 0 && kps.len() > self.params.max_features {
            retain_best(&mut kps, self.params.max_features);
        }
        kps
    }

    /// Unit-norm float descriptors (after the 0.2 clamp and renormalisation, before
    /// quantisation) of the keypoints `kps` in scale space `ss`.
    pub fn describe_in(
        &self,
        ss: &ScaleSpace,
        kps: &[Keypoint],
    ) -> Result<Vec<[f32; DESCRIPTOR_LEN]>, VisionError> {
        // Check every keypoint first, so the (parallel) computation cannot fail.
        let mut jobs = Vec::with_capacity(kps.len());
        for kp in kps {
            jobs.push(descriptor_job(ss, kp)?);
        }
        let level = isa();
        let run =
            |sc: &mut DescScratch,
             &(o, layer, x, y, ori, scl): &(usize, usize, f32, f32, f32, f32)| {
                let img = &ss.octaves[o].gauss[layer];
                let mut v = raw_descriptor(level, img, x, y, ori, scl, sc);
                normalize_descriptor(&mut v);
                v
            };
        #[cfg(feature = "parallel")]
        let out = jobs
            .par_iter()
            .with_min_len(16)
            .map_init(DescScratch::default, run)
            .collect();
        #[cfg(not(feature = "parallel"))]
        let out = {
            let mut sc = DescScratch::default();
            jobs.iter().map(|j| run(&mut sc, j)).collect()
        };
        Ok(out)
    }

    /// Descriptors of given keypoints (as produced by this detector, or by OpenCV: `octave` and
    /// `layer` must name an image of the scale space) in an 8-bit grey image.
    pub fn describe(
        &self,
        img: &Plane<u8>,
        kps: &[Keypoint],
    ) -> Result<Vec<SiftDescriptor>, VisionError> {
        let ss = self.scale_space(&Self::to_f32(img)?)?;
        Ok(self.describe_in(&ss, kps)?.iter().map(quantize).collect())
    }
}

impl FeatureDetector for Sift {
    fn detect(&self, img: &Plane<u8>) -> Result<Vec<Keypoint>, CoreError> {
        self.detect_keypoints(img).map_err(to_core)
    }
}

impl DescriptorExtractor for Sift {
    type Descriptor = SiftDescriptor;
    fn compute(&self, img: &Plane<u8>, kps: &[Keypoint]) -> Result<Vec<SiftDescriptor>, CoreError> {
        self.describe(img, kps).map_err(to_core)
    }
}

impl FeatureExtractor for Sift {
    fn detect_and_compute(
        &self,
        img: &Plane<u8>,
    ) -> Result<(Vec<Keypoint>, Vec<SiftDescriptor>), CoreError> {
        self.extract(img).map_err(to_core)
    }
}

/// Rounds half to even, as OpenCV's `cvRound` (for |v| < 2^22; larger values are already
/// integers and are returned by a plain cast).
#[inline]
fn cv_round(v: f32) -> i32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5·2^23
    if v.abs() < 4_194_304.0 {
        ((v + MAGIC) - MAGIC) as i32
    } else {
        v as i32
    }
}

/// floor(v) for |v| < 2^31 without a libm call (the baseline x86-64 target has no `roundps`).
#[inline]
fn floor_small(v: f32) -> f32 {
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

/// Bilinear ×2 up-sampling with pixel-centre alignment (OpenCV `resize`, `INTER_LINEAR`).
fn upsample2(src: &Plane<f32>) -> Plane<f32> {
    let (w, h) = (src.width as usize, src.height as usize);
    let (w2, h2) = (2 * w, 2 * h);
    // Source index and weight of the second tap for output coordinate i of a side of n pixels.
    let taps = |n: usize, n2: usize| -> Vec<(usize, usize, f32)> {
        (0..n2)
            .map(|i| {
                let f = (i as f32 + 0.5) * 0.5 - 0.5;
                let s = f.floor();
                let mut frac = f - s;
                let mut s = s as isize;
                if s < 0 {
                    s = 0;
                    frac = 0.0;
                }
                let s = s as usize;
                if s >= n - 1 {
                    (n - 1, n - 1, 0.0)
                } else {
                    (s, s + 1, frac)
                }
            })
            .collect()
    };
    let tx = taps(w, w2);
    let ty = taps(h, h2);
    // Horizontal pass for each source row, then vertical interpolation.
    // Both passes are row-parallel with `parallel` (each output value is computed alone).
    let mut hrows = vec![0f32; w2 * h];
    let h_row = |(y, out): (usize, &mut [f32])| {
        let row = &src.data[y * w..(y + 1) * w];
        for (o, &(a, b, f)) in out.iter_mut().zip(&tx) {
            *o = row[a] * (1.0 - f) + row[b] * f;
        }
    };
    let mut data = vec![0f32; w2 * h2];
    let v_row = |hrows: &[f32], (out, &(a, b, f)): (&mut [f32], &(usize, usize, f32))| {
        let ra = &hrows[a * w2..(a + 1) * w2];
        let rb = &hrows[b * w2..(b + 1) * w2];
        for ((o, &va), &vb) in out.iter_mut().zip(ra).zip(rb) {
            *o = va * (1.0 - f) + vb * f;
        }
    };
    #[cfg(feature = "parallel")]
    {
        hrows
            .par_chunks_mut(w2)
            .enumerate()
            .with_min_len(16)
            .for_each(h_row);
        data.par_chunks_mut(w2)
            .zip(ty.par_iter())
            .with_min_len(16)
            .for_each(|x| v_row(&hrows, x));
    }
    #[cfg(not(feature = "parallel"))]
    {
        hrows.chunks_mut(w2).enumerate().for_each(h_row);
        data.chunks_mut(w2)
            .zip(ty.iter())
            .for_each(|x| v_row(&hrows, x));
    }
    Plane {
        width: w2 as u32,
        height: h2 as u32,
        data,
    }
}

/// Decimation by 2: pixel (x, y) ← (2x, 2y).
fn downsample2(src: &Plane<f32>) -> Plane<f32> {
    let (w, h) = (src.width as usize, src.height as usize);
    let (w2, h2) = (w / 2, h / 2);
    let mut data = Vec::with_capacity(w2 * h2);
    for y in 0..h2 {
        let row = &src.data[2 * y * w..2 * y * w + w];
        data.extend(row.iter().step_by(2).take(w2));
    }
    Plane {
        width: w2 as u32,
        height: h2 as u32,
        data,
    }
}

/// Gaussian blur of the scale space: bit-identical to [`crate::blur::gaussian_blur_f32`]
/// (OpenCV's kernel size rule, reflect-101), laid out for speed in [`fast`].
fn blur(src: &Plane<f32>, sigma: f64, tmp: &mut Vec<f32>) -> Result<Plane<f32>, VisionError> {
    Ok(fast::blur(src, &fast::half_kernel(sigma)?, tmp))
}

fn sub_planes(a: &Plane<f32>, b: &Plane<f32>) -> Plane<f32> {
    Plane {
        width: a.width,
        height: a.height,
        data: a.data.iter().zip(&b.data).map(|(x, y)| x - y).collect(),
    }
}

fn build_scale_space(img: &Plane<f32>, p: &SiftParams) -> Result<ScaleSpace, VisionError> {
    let s = p.n_octave_layers as usize;
    let sigma = p.sigma as f32;
    let sin = p.input_blur as f32;
    // Scratch of the horizontal blur pass, shared by every blur of the pyramid.
    let mut tmp = Vec::new();
    let (base, first_octave) = if p.upsample {
        let sig_diff = (sigma * sigma - sin * sin * 4.0).max(0.01).sqrt();
        (blur(&upsample2(img), f64::from(sig_diff), &mut tmp)?, -1)
    } else {
        let sig_diff = (sigma * sigma - sin * sin).max(0.01).sqrt();
        (blur(img, f64::from(sig_diff), &mut tmp)?, 0)
    };
    let min_side = f64::from(base.width.min(base.height));
    let n_oct = ((min_side.log2() - 2.0).round_ties_even() as i32 - first_octave).max(1) as usize;

    // Incremental sigmas (OpenCV's buildGaussianPyramid, in f64).
    let mut sig = vec![p.sigma; s + 3];
    let k = 2f64.powf(1.0 / s as f64);
    for (i, si) in sig.iter_mut().enumerate().skip(1) {
        let prev = k.powi(i as i32 - 1) * p.sigma;
        let total = prev * k;
        *si = (total * total - prev * prev).sqrt();
    }

    let kernels = sig[1..]
        .iter()
        .map(|&si| fast::half_kernel(si))
        .collect::<Result<Vec<_>, _>>()?;
    let mut octaves: Vec<Octave> = Vec::with_capacity(n_oct);
    let mut next_base = Some(base);
    for _ in 0..n_oct {
        let g0 = match next_base.take() {
            Some(b) => b,
            None => match octaves.last() {
                Some(prev) => downsample2(&prev.gauss[s]),
                None => break,
            },
        };
        if g0.width < 2 || g0.height < 2 {
            break;
        }
        let mut gauss = Vec::with_capacity(s + 3);
        gauss.push(g0);
        for k in &kernels {
            let next = fast::blur(&gauss[gauss.len() - 1], k, &mut tmp);
            gauss.push(next);
        }
        octaves.push(Octave { gauss });
    }
    Ok(ScaleSpace {
        octaves,
        first_octave,
        layers: s,
    })
}

#[inline]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

#[inline]
fn fmin(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// Maximum and minimum of the 3×3 block centred on each pixel of row `r` (1 ≤ r < h − 1) of a
/// `w`-wide plane, for columns 1..w−1 (entries 0 and w−1 are left untouched). Branch-free over
/// whole rows so it vectorises.
#[allow(clippy::inline_always)]
#[inline(always)]
fn block3_row(
    p: &[f32],
    w: usize,
    r: usize,
    vmax: &mut [f32],
    vmin: &mut [f32],
    mx: &mut [f32],
    mn: &mut [f32],
) {
    let a = &p[(r - 1) * w..r * w];
    let b = &p[r * w..(r + 1) * w];
    let c = &p[(r + 1) * w..(r + 2) * w];
    for (((hi, lo), (&x, &y)), &z) in vmax
        .iter_mut()
        .zip(vmin.iter_mut())
        .zip(a.iter().zip(b))
        .zip(c)
    {
        *hi = fmax(fmax(x, y), z);
        *lo = fmin(fmin(x, y), z);
    }
    for (k, (hi, lo)) in mx[1..w - 1]
        .iter_mut()
        .zip(mn[1..w - 1].iter_mut())
        .enumerate()
    {
        *hi = fmax(fmax(vmax[k], vmax[k + 1]), vmax[k + 2]);
        *lo = fmin(fmin(vmin[k], vmin[k + 1]), vmin[k + 2]);
    }
}

/// (layer, column) of the pixels of row `r` that are extrema of their 3×3×3 block in DoG
/// layers 1..=s (non-strict, as OpenCV: ≥ all 26 neighbours when positive, ≤ all when
/// negative) with |D| > `thr`, in (layer, column) order. `buf` holds `(2 + 2·layers)·w`
/// scratch values (never needs zeroing: every entry read is written first).
// Non-lazy `&`/`|` on the comparisons keep the block test branch-free (it vectorises).
#[allow(clippy::inline_always, clippy::needless_bitwise_bool)]
#[inline(always)]
fn scan_row_all_layers_body(
    gauss: &[Plane<f32>],
    r: usize,
    w: usize,
    thr: f32,
    buf: &mut [f32],
) -> Vec<(usize, usize)> {
    let nd = gauss.len() - 1;
    let (vmax, rest) = buf.split_at_mut(w);
    let (vmin, rest) = rest.split_at_mut(w);
    let (d3, rest) = rest.split_at_mut(3 * w);
    let (cur_all, rest) = rest.split_at_mut(nd * w);
    let (mx_all, mn_all) = rest.split_at_mut(nd * w);
    for (l, ((mx, mn), cur)) in mx_all
        .chunks_exact_mut(w)
        .zip(mn_all.chunks_exact_mut(w))
        .zip(cur_all.chunks_exact_mut(w))
        .enumerate()
    {
        // Rows r − 1, r, r + 1 of DoG layer l.
        let (g0, g1) = (&gauss[l].data, &gauss[l + 1].data);
        let span = (r - 1) * w..(r + 2) * w;
        for ((o, &a), &b) in d3.iter_mut().zip(&g1[span.clone()]).zip(&g0[span]) {
            *o = a - b;
        }
        cur.copy_from_slice(&d3[w..2 * w]);
        block3_row(d3, w, 1, vmax, vmin, mx, mn);
    }
    let mut out = Vec::new();
    for layer in 1..nd - 1 {
        let cur = &cur_all[layer * w..(layer + 1) * w];
        let (a, b, c) = (
            &mx_all[(layer - 1) * w..layer * w],
            &mx_all[layer * w..(layer + 1) * w],
            &mx_all[(layer + 1) * w..(layer + 2) * w],
        );
        let (d, e, f) = (
            &mn_all[(layer - 1) * w..layer * w],
            &mn_all[layer * w..(layer + 1) * w],
            &mn_all[(layer + 1) * w..(layer + 2) * w],
        );
        // Branch-free test over blocks of 16 columns (vectorises), then the rare hits.
        const B: usize = 16;
        let end = w - IMG_BORDER;
        let mut col = IMG_BORDER;
        while col < end {
            let m = (end - col).min(B);
            let mut hit = [false; B];
            if m == B {
                for (k, h) in hit.iter_mut().enumerate() {
                    let i = col + k;
                    let v = cur[i];
                    let hi = fmax(fmax(a[i], b[i]), c[i]);
                    let lo = fmin(fmin(d[i], e[i]), f[i]);
                    *h = ((v > thr) & (v >= hi)) | ((v < -thr) & (v <= lo));
                }
            } else {
                for (k, h) in hit.iter_mut().enumerate().take(m) {
                    let i = col + k;
                    let v = cur[i];
                    let hi = fmax(fmax(a[i], b[i]), c[i]);
                    let lo = fmin(fmin(d[i], e[i]), f[i]);
                    *h = ((v > thr) & (v >= hi)) | ((v < -thr) & (v <= lo));
                }
            }
            if hit.iter().any(|&h| h) {
                out.extend(
                    hit.iter()
                        .enumerate()
                        .filter(|&(_, &h)| h)
                        .map(|(k, _)| (layer, col + k)),
                );
            }
            col += m;
        }
    }
    out
}

multiversion!(fn scan_row_all_layers => scan_row_all_layers_body(
    gauss: &[Plane<f32>],
    r: usize,
    w: usize,
    thr: f32,
    buf: &mut [f32],
) -> Vec<(usize, usize)>);

/// A refined extremum.
#[derive(Debug, Clone, Copy)]
struct Refined {
    octave: usize,
    layer: usize,
    r: usize,
    c: usize,
    kp: Keypoint,
}

/// Quadratic sub-pixel refinement with the contrast and edge tests (OpenCV's
/// `adjustLocalExtrema`). `octave` is the internal index (0 = first octave).
fn refine(
    ss: &ScaleSpace,
    p: &SiftParams,
    octave: usize,
    layer0: usize,
    r0: usize,
    c0: usize,
) -> Option<Refined> {
    const IMG_SCALE: f32 = 1.0 / 255.0;
    const DERIV: f32 = IMG_SCALE * 0.5;
    const SECOND: f32 = IMG_SCALE;
    const CROSS: f32 = IMG_SCALE * 0.25;
    let s = ss.layers;
    let g = &ss.octaves[octave].gauss;
    let w = g[0].width as usize;
    let h = g[0].height as usize;
    let (mut layer, mut r, mut c) = (layer0 as i64, r0 as i64, c0 as i64);
    let (mut xi, mut xr, mut xc) = (0f32, 0f32, 0f32);
    let mut grad = [0f32; 3];
    let mut converged = false;
    for _ in 0..MAX_INTERP_STEPS {
        let (l, ri, ci) = (layer as usize, r as usize, c as usize);
        let (img, prv, nxt) = (l, l - 1, l + 1);
        // DoG layer `d` at (y, x).
        let at = |d: usize, y: usize, x: usize| g[d + 1].data[y * w + x] - g[d].data[y * w + x];
        grad = [
            (at(img, ri, ci + 1) - at(img, ri, ci - 1)) * DERIV,
            (at(img, ri + 1, ci) - at(img, ri - 1, ci)) * DERIV,
            (at(nxt, ri, ci) - at(prv, ri, ci)) * DERIV,
        ];
        let v2 = at(img, ri, ci) * 2.0;
        let dxx = (at(img, ri, ci + 1) + at(img, ri, ci - 1) - v2) * SECOND;
        let dyy = (at(img, ri + 1, ci) + at(img, ri - 1, ci) - v2) * SECOND;
        let dss = (at(nxt, ri, ci) + at(prv, ri, ci) - v2) * SECOND;
        let dxy = (at(img, ri + 1, ci + 1) - at(img, ri + 1, ci - 1) - at(img, ri - 1, ci + 1)
            + at(img, ri - 1, ci - 1))
            * CROSS;
        let dxs = (at(nxt, ri, ci + 1) - at(nxt, ri, ci - 1) - at(prv, ri, ci + 1)
            + at(prv, ri, ci - 1))
            * CROSS;
        let dys = (at(nxt, ri + 1, ci) - at(nxt, ri - 1, ci) - at(prv, ri + 1, ci)
            + at(prv, ri - 1, ci))
            * CROSS;
        let hm = nalgebra::Matrix3::new(dxx, dxy, dxs, dxy, dyy, dys, dxs, dys, dss);
        let x = hm
            .lu()
            .solve(&nalgebra::Vector3::new(grad[0], grad[1], grad[2]))?;
        xc = -x[0];
        xr = -x[1];
        xi = -x[2];
        if !(xc.is_finite() && xr.is_finite() && xi.is_finite()) {
            return None;
        }
        if xi.abs() < 0.5 && xr.abs() < 0.5 && xc.abs() < 0.5 {
            converged = true;
            break;
        }
        const BIG: f32 = (i32::MAX / 3) as f32;
        if xi.abs() > BIG || xr.abs() > BIG || xc.abs() > BIG {
            return None;
        }
        c += i64::from(cv_round(xc));
        r += i64::from(cv_round(xr));
        layer += i64::from(cv_round(xi));
        if layer < 1
            || layer > s as i64
            || c < IMG_BORDER as i64
            || c >= (w - IMG_BORDER) as i64
            || r < IMG_BORDER as i64
            || r >= (h - IMG_BORDER) as i64
        {
            return None;
        }
    }
    if !converged {
        return None;
    }
    let (l, ri, ci) = (layer as usize, r as usize, c as usize);
    let at = |y: usize, x: usize| g[l + 1].data[y * w + x] - g[l].data[y * w + x];
    let t = grad[0] * xc + grad[1] * xr + grad[2] * xi;
    let contr = at(ri, ci) * IMG_SCALE + t * 0.5;
    if contr.abs() * (s as f32) < p.contrast_threshold as f32 {
        return None;
    }
    let v2 = at(ri, ci) * 2.0;
    let dxx = (at(ri, ci + 1) + at(ri, ci - 1) - v2) * SECOND;
    let dyy = (at(ri + 1, ci) + at(ri - 1, ci) - v2) * SECOND;
    let dxy =
        (at(ri + 1, ci + 1) - at(ri + 1, ci - 1) - at(ri - 1, ci + 1) + at(ri - 1, ci - 1)) * CROSS;
    let tr = dxx + dyy;
    let det = dxx * dyy - dxy * dxy;
    let et = p.edge_threshold as f32;
    if det <= 0.0 || tr * tr * et >= (et + 1.0) * (et + 1.0) * det {
        return None;
    }
    // Position and size as OpenCV computes them in the internal octave, then scaled to input
    // pixels (×0.5 for the up-sampled octave).
    let mult = (1u64 << octave) as f32;
    let mut x = (ci as f32 + xc) * mult;
    let mut y = (ri as f32 + xr) * mult;
    let mut size = (p.sigma as f32) * 2f32.powf((l as f32 + xi) / s as f32) * mult * 2.0;
    if ss.first_octave < 0 {
        let scale = 0.5f32.powi(-ss.first_octave);
        x *= scale;
        y *= scale;
        size *= scale;
    }
    Some(Refined {
        octave,
        layer: l,
        r: ri,
        c: ci,
        kp: Keypoint {
            x,
            y,
            sigma: size * 0.5,
            angle_deg: 0.0,
            response: contr.abs(),
            octave: octave as i32 + ss.first_octave,
            layer: l as i32,
            layer_offset: xi,
        },
    })
}

/// The smoothed 36-bin orientation histogram around (c, r) (OpenCV's `calcOrientationHist`);
/// returns its maximum.
#[allow(clippy::inline_always)]
#[inline(always)]
fn orientation_hist_body(
    img: &Plane<f32>,
    r0: usize,
    c0: usize,
    radius: i32,
    sigma: f32,
    hist: &mut [f32; ORI_HIST_BINS],
) -> f32 {
    let w = img.width as i32;
    let h = img.height as i32;
    let n = ORI_HIST_BINS;
    let expf_scale = -1.0 / (2.0 * sigma * sigma);
    let mut raw = [0f32; ORI_HIST_BINS];
    let d = &img.data;
    // Row by row over the window's columns inside the image without its outer ring (a
    // contiguous run): gather, evaluate exp/atan2/sqrt over the run (vectorised), accumulate
    // in OpenCV's order (row-major).
    let jmin = (-radius).max(1 - c0 as i32);
    let jmax = radius.min(w - 2 - c0 as i32);
    if jmin <= jmax {
        let (c, r) = (c0 as i32, r0 as i32);
        touch_window(
            d,
            w as usize,
            c + jmin - 1,
            c + jmax + 1,
            r - radius - 1,
            r + radius + 1,
            h,
        );
        let len = (jmax - jmin + 1) as usize;
        let mut gx = [0f32; ORI_RUN];
        let mut gy = [0f32; ORI_RUN];
        let mut gw = [0f32; ORI_RUN];
        let wu = w as usize;
        for i in -radius..=radius {
            let y = r0 as i32 + i;
            if y <= 0 || y >= h - 1 {
                continue;
            }
            let row0 = (y * w + c0 as i32 + jmin) as usize;
            // Runs longer than the stack buffers are split (same order of accumulation).
            let mut off = 0;
            while off < len {
                let m = (len - off).min(ORI_RUN);
                let at = row0 + off;
                let (right, left) = (&d[at + 1..at + 1 + m], &d[at - 1..at - 1 + m]);
                let (up, down) = (&d[at - wu..at - wu + m], &d[at + wu..at + wu + m]);
                for (((o, &a), &b), (p, (&u, &v))) in gx[..m]
                    .iter_mut()
                    .zip(right)
                    .zip(left)
                    .zip(gy[..m].iter_mut().zip(up.iter().zip(down)))
                {
                    *o = a - b;
                    *p = u - v;
                }
                let j0 = jmin + off as i32;
                for (k, g) in gw[..m].iter_mut().enumerate() {
                    let j = j0 + k as i32;
                    *g = ((i * i + j * j) as f32) * expf_scale;
                }
                for ((wgt, dx), &dy) in gw[..m].iter_mut().zip(gx[..m].iter_mut()).zip(&gy[..m]) {
                    let gdx = *dx;
                    *dx = fast_atan2(dy, gdx) * (n as f32 / 360.0);
                    *wgt = fast_exp(*wgt) * (gdx * gdx + dy * dy).sqrt();
                }
                for (&o, &m) in gx[..m].iter().zip(&gw[..m]) {
                    let mut bin = cv_round(o);
                    if bin >= n as i32 {
                        bin -= n as i32;
                    }
                    if bin < 0 {
                        bin += n as i32;
                    }
                    raw[bin as usize] += m;
                }
                off += m;
            }
        }
    }
    let mut maxval = 0f32;
    for i in 0..n {
        let at = |k: isize| raw[k.rem_euclid(n as isize) as usize];
        let ii = i as isize;
        hist[i] = (at(ii - 2) + at(ii + 2)) * (1.0 / 16.0)
            + (at(ii - 1) + at(ii + 1)) * (4.0 / 16.0)
            + raw[i] * (6.0 / 16.0);
        maxval = maxval.max(hist[i]);
    }
    maxval
}

/// Longest run of window columns processed at once by the orientation histogram.
const ORI_RUN: usize = 128;

multiversion!(fn orientation_hist => orientation_hist_body(
    img: &Plane<f32>,
    r0: usize,
    c0: usize,
    radius: i32,
    sigma: f32,
    hist: &mut [f32; ORI_HIST_BINS],
) -> f32);

/// The keypoints (one per orientation peak) of a refined extremum.
fn orient(ss: &ScaleSpace, rf: &Refined, out: &mut Vec<Keypoint>) {
    let n = ORI_HIST_BINS;
    let img = &ss.octaves[rf.octave].gauss[rf.layer];
    // σ in octave pixels: size·0.5 / 2^octave with the internal octave index.
    let scl_octv = rf.kp.sigma * 2f32.powi(-(rf.kp.octave));
    let mut hist = [0f32; ORI_HIST_BINS];
    let omax = orientation_hist(
        isa(),
        img,
        rf.r,
        rf.c,
        cv_round(ORI_RADIUS * scl_octv),
        ORI_SIG_FCTR * scl_octv,
        &mut hist,
    );
    let mag_thr = omax * ORI_PEAK_RATIO;
    for j in 0..n {
        let l = if j > 0 { j - 1 } else { n - 1 };
        let r2 = if j < n - 1 { j + 1 } else { 0 };
        if hist[j] > hist[l] && hist[j] > hist[r2] && hist[j] >= mag_thr {
            let mut bin =
                j as f32 + 0.5 * (hist[l] - hist[r2]) / (hist[l] - 2.0 * hist[j] + hist[r2]);
            if bin < 0.0 {
                bin += n as f32;
            } else if bin >= n as f32 {
                bin -= n as f32;
            }
            let mut angle = 360.0 - (360.0 / n as f32) * bin;
            if (angle - 360.0).abs() < f32::EPSILON {
                angle = 0.0;
            }
            out.push(Keypoint {
                angle_deg: angle,
                ..rf.kp
            });
        }
    }
}

fn find_keypoints(ss: &ScaleSpace, p: &SiftParams) -> Vec<Keypoint> {
    let s = ss.layers;
    // OpenCV's pre-threshold in 0..255 units, floored to an integer (spec 004 §4.3).
    let thr = (0.5 * p.contrast_threshold / s as f64 * 255.0).floor() as f32;
    let mut cands: Vec<(usize, usize, usize, usize)> = Vec::new();
    for (o, oct) in ss.octaves.iter().enumerate() {
        let w = oct.gauss[0].width as usize;
        let h = oct.gauss[0].height as usize;
        if w <= 2 * IMG_BORDER || h <= 2 * IMG_BORDER {
            continue;
        }
        // One pass over the rows: the 3×3 block max/min rows of every DoG layer are computed
        // once per row and shared by the s centre layers that use them.
        let nd = oct.gauss.len() - 1;
        let level = isa();
        let scan_row = |buf: &mut Vec<f32>, r: usize| -> Vec<(usize, usize)> {
            scan_row_all_layers(level, &oct.gauss, r, w, thr, buf)
        };
        let buf_len = (5 + 3 * nd) * w;
        #[cfg(feature = "parallel")]
        let rows: Vec<Vec<(usize, usize)>> = (IMG_BORDER..h - IMG_BORDER)
            .into_par_iter()
            .with_min_len(8)
            .map_init(|| vec![0f32; buf_len], scan_row)
            .collect();
        #[cfg(not(feature = "parallel"))]
        let rows: Vec<Vec<(usize, usize)>> = {
            let mut buf = vec![0f32; buf_len];
            (IMG_BORDER..h - IMG_BORDER)
                .map(|r| scan_row(&mut buf, r))
                .collect()
        };
        // Candidates in (layer, row, column) order, as a layer-by-layer scan gives them.
        for layer in 1..=s {
            for (k, row) in rows.iter().enumerate() {
                let r = IMG_BORDER + k;
                cands.extend(
                    row.iter()
                        .filter(|&&(l, _)| l == layer)
                        .map(|&(l, c)| (o, l, r, c)),
                );
            }
        }
    }
    let run = |&(o, layer, r, c): &(usize, usize, usize, usize)| -> Vec<Keypoint> {
        let mut out = Vec::new();
        if let Some(rf) = refine(ss, p, o, layer, r, c) {
            orient(ss, &rf, &mut out);
        }
        out
    };
    #[cfg(feature = "parallel")]
    let per: Vec<Vec<Keypoint>> = cands.par_iter().with_min_len(32).map(run).collect();
    #[cfg(not(feature = "parallel"))]
    let per: Vec<Vec<Keypoint>> = cands.iter().map(run).collect();
    per.into_iter().flatten().collect()
}

fn kp_cmp(a: &Keypoint, b: &Keypoint) -> std::cmp::Ordering {
    a.x.total_cmp(&b.x)
        .then(a.y.total_cmp(&b.y))
        .then(b.sigma.total_cmp(&a.sigma))
        .then(a.angle_deg.total_cmp(&b.angle_deg))
        .then(b.response.total_cmp(&a.response))
        .then(a.octave.cmp(&b.octave))
        .then(a.layer.cmp(&b.layer))
        .then(a.layer_offset.total_cmp(&b.layer_offset))
}

/// Sorts keypoints and removes those with the same position, size and angle as the previous one.
fn sort_dedup(kps: &mut Vec<Keypoint>) {
    kps.sort_by(kp_cmp);
    kps.dedup_by(|b, a| {
        a.x == b.x && a.y == b.y && a.sigma == b.sigma && a.angle_deg == b.angle_deg
    });
}

/// Keeps the `n` strongest keypoints (ties at the cut kept, as OpenCV's `retainBest`), in the
/// sorted order.
fn retain_best(kps: &mut Vec<Keypoint>, n: usize) {
    let mut resp: Vec<f32> = kps.iter().map(|k| k.response).collect();
    resp.sort_by(|a, b| b.total_cmp(a));
    let cut = resp[n - 1];
    kps.retain(|k| k.response >= cut);
}

type DescriptorJob = (usize, usize, f32, f32, f32, f32);

/// Where and how to compute the descriptor of `kp`: (internal octave, layer, x, y in octave
/// pixels, y-up orientation in degrees, σ in octave pixels).
fn descriptor_job(ss: &ScaleSpace, kp: &Keypoint) -> Result<DescriptorJob, VisionError> {
    let finite =
        kp.x.is_finite() && kp.y.is_finite() && kp.sigma.is_finite() && kp.angle_deg.is_finite();
    if !finite || kp.sigma <= 0.0 {
        return Err(VisionError::NonFinite("keypoint (x, y, sigma, angle)"));
    }
    let o = kp.octave - ss.first_octave;
    if o < 0 || o as usize >= ss.octaves.len() {
        return Err(CoreError::invalid(
            "keypoint octave",
            format!(
                "{} outside the scale space's octaves {}..{}",
                kp.octave,
                ss.first_octave,
                ss.first_octave + ss.octaves.len() as i32
            ),
        )
        .into());
    }
    if kp.layer < 0 || kp.layer as usize >= ss.layers + 3 {
        return Err(CoreError::invalid(
            "keypoint layer",
            format!("{} outside 0..{}", kp.layer, ss.layers + 3),
        )
        .into());
    }
    let scale = 2f32.powi(-kp.octave);
    let mut ori = 360.0 - kp.angle_deg;
    if (ori - 360.0).abs() < f32::EPSILON {
        ori = 0.0;
    }
    let x = kp.x * scale;
    let y = kp.y * scale;
    if x.abs() > 1e7 || y.abs() > 1e7 {
        return Err(CoreError::invalid("keypoint position", "far outside the image").into());
    }
    Ok((
        o as usize,
        kp.layer as usize,
        x,
        y,
        ori,
        kp.sigma * 2.0 * scale * 0.5,
    ))
}

/// Per-worker scratch of the descriptor: gathered samples (structure of arrays), flushed into
/// the histogram in chunks so that memory stays bounded for any keypoint size.
#[derive(Default)]
struct DescScratch {
    dx: Vec<f32>,
    dy: Vec<f32>,
    rbin: Vec<f32>,
    cbin: Vec<f32>,
    w: Vec<f32>,
}

/// Samples gathered before they are accumulated (the order of accumulation is the gathering
/// order, so chunking does not change the sums).
const DESC_CHUNK: usize = 1024;

/// Samples whose trilinear weights are computed together (vectorised) before being scattered.
const DESC_BLOCK: usize = 16;

impl DescScratch {
    fn ensure(&mut self, n: usize) {
        for v in [
            &mut self.dx,
            &mut self.dy,
            &mut self.rbin,
            &mut self.cbin,
            &mut self.w,
        ] {
            if v.len() < n {
                v.resize(n, 0.0);
            }
        }
    }
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

/// The raw 128-bin histogram (OpenCV's `calcSIFTDescriptor` before normalisation).
///
/// The samples of one window row that pass OpenCV's per-sample test
/// (`-1 < rbin < d`, `-1 < cbin < d`, inside the image without its outer pixel ring) form one
/// contiguous run of columns: `rbin` and `cbin` are monotone in the column (IEEE rounding of a
/// product with a fixed factor and of a sum with a fixed term are monotone), so each test holds
/// on an interval. The run's ends are found with the per-sample test itself, and the run is
/// processed with whole-slice loops that vectorise; the samples, their values and the order in
/// which they are accumulated are exactly OpenCV's (and the previous scalar loop's).
#[allow(clippy::inline_always)]
#[inline(always)]
fn raw_descriptor_body(
    img: &Plane<f32>,
    ptx: f32,
    pty: f32,
    ori: f32,
    scl: f32,
    sc: &mut DescScratch,
) -> [f32; DESCRIPTOR_LEN] {
    const D: usize = DESCR_WIDTH;
    const N: usize = DESCR_HIST_BINS;
    let px = cv_round(ptx);
    let py = cv_round(pty);
    let rad = ori * (std::f32::consts::PI / 180.0);
    let mut cos_t = rad.cos();
    let mut sin_t = rad.sin();
    let bins_per_rad = N as f32 / 360.0;
    let exp_scale = -1.0 / (D as f32 * D as f32 * 0.5);
    let hist_width = DESCR_SCL_FCTR * scl;
    let rows = img.height as i32;
    let cols = img.width as i32;
    let diag =
        (f64::from(cols) * f64::from(cols) + f64::from(rows) * f64::from(rows)).sqrt() as i32;
    let radius = cv_round(hist_width * std::f32::consts::SQRT_2 * (D as f32 + 1.0) * 0.5).min(diag);
    cos_t /= hist_width;
    sin_t /= hist_width;
    let mut hist = [0f32; (D + 2) * (D + 2) * (N + 2)];
    let data = &img.data;
    let half = D as f32 / 2.0 - 0.5;
    // Columns j of the window inside the image without its outer ring: 0 < px + j < cols − 1.
    let jmin = (-radius).max(1 - px);
    let jmax = radius.min(cols - 2 - px);
    let run_max = (jmax - jmin + 1).max(0) as usize;
    sc.ensure(DESC_CHUNK + run_max + DESC_BLOCK);
    if jmin <= jmax {
        touch_window(
            data,
            cols as usize,
            px + jmin - 1,
            px + jmax + 1,
            py - radius - 1,
            py + radius + 1,
            rows,
        );
    }
    let mut n = 0usize;
    for i in -radius..=radius {
        let r = py + i;
        if r <= 0 || r >= rows - 1 || jmin > jmax {
            continue;
        }
        let fi = i as f32;
        let inside = |j: i32| -> bool {
            let fj = j as f32;
            let c_rot = fj * cos_t - fi * sin_t;
            let r_rot = fj * sin_t + fi * cos_t;
            let rbin = r_rot + half;
            let cbin = c_rot + half;
            rbin > -1.0 && rbin < D as f32 && cbin > -1.0 && cbin < D as f32
        };
        let mut lo = jmin;
        while lo <= jmax && !inside(lo) {
            lo += 1;
        }
        if lo > jmax {
            continue;
        }
        let mut hi = jmax;
        while !inside(hi) {
            hi -= 1;
        }
        let len = (hi - lo + 1) as usize;
        let row = (r * cols) as usize;
        let c0 = (px + lo) as usize;
        let cu = cols as usize;
        let mid = &data[row + c0..row + c0 + len];
        let left = &data[row + c0 - 1..row + c0 - 1 + len];
        let right = &data[row + c0 + 1..row + c0 + 1 + len];
        let up = &data[row + c0 - cu..row + c0 - cu + len];
        let down = &data[row + c0 + cu..row + c0 + cu + len];
        let _ = mid;
        for ((o, &a), &b) in sc.dx[n..n + len].iter_mut().zip(right).zip(left) {
            *o = a - b;
        }
        for ((o, &a), &b) in sc.dy[n..n + len].iter_mut().zip(up).zip(down) {
            *o = a - b;
        }
        let fisin = fi * sin_t;
        let ficos = fi * cos_t;
        for (k, ((rb, cb), wt)) in sc.rbin[n..n + len]
            .iter_mut()
            .zip(&mut sc.cbin[n..n + len])
            .zip(&mut sc.w[n..n + len])
            .enumerate()
        {
            let fj = (lo + k as i32) as f32;
            let c_rot = fj * cos_t - fisin;
            let r_rot = fj * sin_t + ficos;
            *rb = r_rot + half;
            *cb = c_rot + half;
            *wt = (c_rot * c_rot + r_rot * r_rot) * exp_scale;
        }
        n += len;
        if n >= DESC_CHUNK {
            accumulate_descriptor(sc, n, ori, bins_per_rad, &mut hist);
            n = 0;
        }
    }
    accumulate_descriptor(sc, n, ori, bins_per_rad, &mut hist);
    let mut dst = [0f32; DESCRIPTOR_LEN];
    for i in 0..D {
        for j in 0..D {
            let idx = ((i + 1) * (D + 2) + (j + 1)) * (N + 2);
            hist[idx] += hist[idx + N];
            hist[idx + 1] += hist[idx + N + 1];
            dst[(i * D + j) * N..(i * D + j + 1) * N].copy_from_slice(&hist[idx..idx + N]);
        }
    }
    dst
}

multiversion!(fn raw_descriptor => raw_descriptor_body(
    img: &Plane<f32>,
    ptx: f32,
    pty: f32,
    ori: f32,
    scl: f32,
    sc: &mut DescScratch,
) -> [f32; DESCRIPTOR_LEN]);

/// Loads one value per cache line of the columns `c0..=c1` of rows `r0..=r1` (clipped to
/// the image) so that the cache misses of a keypoint's window overlap instead of arriving one
/// row at a time inside the gathering loop (a software prefetch without `unsafe`).
#[allow(clippy::inline_always)]
#[inline(always)]
fn touch_window(data: &[f32], cols: usize, c0: i32, c1: i32, r0: i32, r1: i32, rows: i32) {
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

/// Accumulates the first `n` gathered samples of `sc` into the descriptor histogram
/// (orientation, magnitude, Gaussian weight, then OpenCV's trilinear split), in order.
#[allow(clippy::inline_always)]
#[inline(always)]
fn accumulate_descriptor(
    sc: &mut DescScratch,
    n: usize,
    ori: f32,
    bins_per_rad: f32,
    hist: &mut [f32; (DESCR_WIDTH + 2) * (DESCR_WIDTH + 2) * (DESCR_HIST_BINS + 2)],
) {
    const D: usize = DESCR_WIDTH;
    const N: usize = DESCR_HIST_BINS;
    const B: usize = DESC_BLOCK;
    // Orientation into `dx`, weighted magnitude into `dy` (in place, vectorisable).
    for ((dx, dy), &w) in sc.dx[..n]
        .iter_mut()
        .zip(sc.dy[..n].iter_mut())
        .zip(&sc.w[..n])
    {
        let (gx, gy) = (*dx, *dy);
        *dx = fast_atan2(gy, gx);
        *dy = (gx * gx + gy * gy).sqrt() * fast_exp(w);
    }
    let rs = (D + 2) * (N + 2);
    let mut start = 0;
    while start < n {
        // Weights of a whole block of B samples (lanes past `n` hold stale values and are not
        // scattered), then the scatter of the `m` real ones, in order.
        let m = (n - start).min(B);
        let mut idx = [0usize; B];
        let mut v = [[0f32; B]; 8];
        let (ori_v, mag_v) = (&sc.dx[start..start + B], &sc.dy[start..start + B]);
        let (rb_v, cb_v) = (&sc.rbin[start..start + B], &sc.cbin[start..start + B]);
        for k in 0..B {
            let (rbin, cbin, mag) = (rb_v[k], cb_v[k], mag_v[k]);
            let obin = (ori_v[k] - ori) * bins_per_rad;
            let r0 = floor_small(rbin);
            let c0 = floor_small(cbin);
            let o0f = floor_small(obin);
            let (rf, cf, of) = (rbin - r0, cbin - c0, obin - o0f);
            let (r0, c0) = (r0 as i32, c0 as i32);
            let mut o0 = o0f as i32;
            if o0 < 0 {
                o0 += N as i32;
            }
            if o0 >= N as i32 {
                o0 -= N as i32;
            }
            let v_r1 = mag * rf;
            let v_r0 = mag - v_r1;
            let v_rc11 = v_r1 * cf;
            let v_rc10 = v_r1 - v_rc11;
            let v_rc01 = v_r0 * cf;
            let v_rc00 = v_r0 - v_rc01;
            let v_rco111 = v_rc11 * of;
            let v_rco101 = v_rc10 * of;
            let v_rco011 = v_rc01 * of;
            let v_rco001 = v_rc00 * of;
            v[0][k] = v_rc00 - v_rco001;
            v[1][k] = v_rco001;
            v[2][k] = v_rc01 - v_rco011;
            v[3][k] = v_rco011;
            v[4][k] = v_rc10 - v_rco101;
            v[5][k] = v_rco101;
            v[6][k] = v_rc11 - v_rco111;
            v[7][k] = v_rco111;
            // Stale lanes may give a negative index; it is never used (`k >= m`).
            idx[k] = (((r0 + 1) * (D as i32 + 2) + c0 + 1) * (N as i32 + 2) + o0) as usize;
        }
        for k in 0..m {
            let i = idx[k];
            hist[i] += v[0][k];
            hist[i + 1] += v[1][k];
            hist[i + N + 2] += v[2][k];
            hist[i + N + 3] += v[3][k];
            hist[i + rs] += v[4][k];
            hist[i + rs + 1] += v[5][k];
            hist[i + rs + N + 2] += v[6][k];
            hist[i + rs + N + 3] += v[7][k];
        }
        start += m;
    }
}

/// Clamps every element at 0.2·‖v‖₂ and renormalises to unit L2 norm (a zero vector stays
/// zero).
pub fn normalize_descriptor(v: &mut [f32; DESCRIPTOR_LEN]) {
    let nrm = v.iter().map(|x| x * x).sum::<f32>().sqrt();
    let thr = nrm * DESCR_MAG_THR;
    let mut nrm2 = 0f32;
    for x in v.iter_mut() {
        *x = x.min(thr);
        nrm2 += *x * *x;
    }
    let inv = 1.0 / nrm2.sqrt().max(f32::EPSILON);
    for x in v.iter_mut() {
        *x *= inv;
    }
}

/// Quantises a unit-norm descriptor: `saturate_u8(round(512·v))` (OpenCV's output).
pub fn quantize(v: &[f32; DESCRIPTOR_LEN]) -> SiftDescriptor {
    let mut q = [0u8; DESCRIPTOR_LEN];
    for (o, &x) in q.iter_mut().zip(v) {
        *o = (x * INT_DESCR_FCTR).round_ties_even().clamp(0.0, 255.0) as u8;
    }
    q
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

    #[test]
    fn upsample_is_centre_aligned() {
        let src = Plane::from_vec(2, 1, vec![0.0f32, 4.0]).unwrap();
        let up = upsample2(&src);
        assert_eq!((up.width, up.height), (4, 2));
        assert_eq!(&up.data[..4], &[0.0, 1.0, 3.0, 4.0]);
    }

    #[test]
    fn downsample_takes_even_pixels() {
        let src = Plane::from_fn(5, 5, |x, y| (x + 10 * y) as f32);
        let d = downsample2(&src);
        assert_eq!((d.width, d.height), (2, 2));
        assert_eq!(d.data, vec![0.0, 2.0, 20.0, 22.0]);
    }

    #[test]
    fn normalisation_gives_unit_norm_and_clamps() {
        let mut v = [0f32; DESCRIPTOR_LEN];
        v[0] = 10.0;
        v[1] = 1.0;
        v[2] = 1.0;
        normalize_descriptor(&mut v);
        let n: f32 = v.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!((n - 1.0).abs() < 1e-6);
        // The large element was clamped to 0.2 of the norm before renormalising.
        assert!((v[0] / v[1] - 0.2 * (102f32).sqrt()).abs() < 1e-4);
        let q = quantize(&v);
        assert!(q[0] > q[1]);
    }

    #[test]
    fn bad_params_are_rejected() {
        let p = SiftParams {
            sigma: f64::NAN,
            ..SiftParams::default()
        };
        assert!(Sift::new(p).is_err());
        let p = SiftParams {
            n_octave_layers: 0,
            ..SiftParams::default()
        };
        assert!(Sift::new(p).is_err());
    }
}
