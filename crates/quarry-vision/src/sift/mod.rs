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
//!
//! # Layout
//! - this file: the parameters ([`SiftParams`]), the extractor ([`Sift`]) and its
//!   `quarry_core` trait implementations;
//! - `scale_space`: the Gaussian pyramid ([`ScaleSpace`]), up- and down-sampling;
//! - `fast`: the register-blocked Gaussian blur of the pyramid;
//! - `extrema`: the DoG extremum scan, sub-pixel refinement with the contrast and edge tests,
//!   and the ordering / selection of the keypoints;
//! - `orientation`: the orientation histogram and one keypoint per dominant orientation;
//! - `descriptor`: the 128-bin descriptor, its normalisation ([`normalize_descriptor`]) and
//!   quantisation ([`quantize`]);
//! - `util`: OpenCV's rounding, `fastAtan2` and `exp32f`, and other helpers shared by the stages.

use crate::VisionError;
use quarry_core::{
    CoreError, DescriptorExtractor, FeatureDetector, FeatureExtractor, Keypoint, Plane,
};
use serde::{Deserialize, Serialize};

mod descriptor;
mod extrema;
mod fast;
mod orientation;
mod scale_space;
mod util;

pub use descriptor::{normalize_descriptor, quantize};
pub use scale_space::ScaleSpace;

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
        scale_space::build_scale_space(img, &self.params)
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
        let mut kps = extrema::find_keypoints(ss, &self.params);
        extrema::sort_dedup(&mut kps);
        if self.params.max_features > 0 && kps.len() > self.params.max_features {
            extrema::retain_best(&mut kps, self.params.max_features);
        }
        kps
    }

    /// The keypoints of [`detect_in`](Self::detect_in) whose position `(x, y)` (input-image
    /// pixels) passes `keep`, in the same order: exactly `detect_in(ss)` filtered by `keep`,
    /// but only the extrema that pass are given orientations, which saves most of the work
    /// when few are wanted (the padding of a crop, say). With `max_features > 0` every keypoint
    /// is detected first, since the cut to the strongest needs all of them.
    pub fn detect_in_where(
        &self,
        ss: &ScaleSpace,
        keep: impl Fn(f32, f32) -> bool + Sync,
    ) -> Vec<Keypoint> {
        if self.params.max_features > 0 {
            let mut kps = self.detect_in(ss);
            kps.retain(|k| keep(k.x, k.y));
            return kps;
        }
        let mut kps = extrema::find_keypoints_where(ss, &self.params, &keep);
        extrema::sort_dedup(&mut kps);
        kps
    }

    /// Unit-norm float descriptors (after the 0.2 clamp and renormalisation, before
    /// quantisation) of the keypoints `kps` in scale space `ss`.
    pub fn describe_in(
        &self,
        ss: &ScaleSpace,
        kps: &[Keypoint],
    ) -> Result<Vec<[f32; DESCRIPTOR_LEN]>, VisionError> {
        descriptor::describe(ss, kps)
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

#[cfg(test)]
mod tests {
    use super::*;

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
