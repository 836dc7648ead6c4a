//! Vision vocabulary: segmentation and local features.

use crate::{CoreError, Plane};

/// One regional minimum (a watershed seed).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct MinimumInfo {
    /// The label of the minimum (and of its region), starting at 1.
    pub id: u32,
    /// One pixel `(x, y)` of the minimum (quarry-vision picks the plateau pixel nearest the
    /// centroid, spec 004 §2.4).
    pub representative: (u32, u32),
    /// Number of pixels of the minimum plateau.
    pub size: usize,
    /// The grey value at the minimum.
    pub value: f64,
}

/// A label image and the minima that seeded it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Segmentation {
    /// Label of each pixel; region `k` grew from `minima[k - 1]`. 0 only where a segmenter
    /// documents it (watershed lines).
    pub labels: Plane<u32>,
    /// The seeds, by label.
    pub minima: Vec<MinimumInfo>,
}

impl Segmentation {
    /// Number of regions.
    pub fn n_regions(&self) -> usize {
        self.minima.len()
    }
}

/// Segments a grey frame into regions.
pub trait Segmenter {
    /// Segments `frame`.
    fn segment(&self, frame: &Plane<u8>) -> Result<Segmentation, CoreError>;
}

/// A scale-space keypoint, OpenCV-compatible where it matters.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Keypoint {
    /// Column in input pixels (centre of the top-left pixel at 0).
    pub x: f32,
    /// Row in input pixels.
    pub y: f32,
    /// Scale σ in input pixels (OpenCV's `size` is `2σ`).
    pub sigma: f32,
    /// Orientation in degrees, OpenCV convention (`KeyPoint.angle`).
    pub angle_deg: f32,
    /// Detector response (|DoG| for SIFT).
    pub response: f32,
    /// Octave (-1 for an up-sampled first octave).
    pub octave: i32,
    /// Layer within the octave.
    pub layer: i32,
    /// Sub-layer offset from the quadratic refinement.
    pub layer_offset: f32,
}

impl Keypoint {
    /// OpenCV's `KeyPoint.size` (the diameter, `2σ`).
    pub fn size(&self) -> f32 {
        2.0 * self.sigma
    }
}

/// Finds keypoints in a grey image.
pub trait FeatureDetector {
    /// Detects keypoints.
    fn detect(&self, img: &Plane<u8>) -> Result<Vec<Keypoint>, CoreError>;
}

/// Computes a descriptor per keypoint.
pub trait DescriptorExtractor {
    /// The descriptor type (`[u8; 128]` for SIFT).
    type Descriptor;
    /// One descriptor per keypoint, in order.
    fn compute(
        &self,
        img: &Plane<u8>,
        kps: &[Keypoint],
    ) -> Result<Vec<Self::Descriptor>, CoreError>;
}

/// Detection and description in one pass (SIFT builds its pyramid once).
pub trait FeatureExtractor: FeatureDetector + DescriptorExtractor {
    /// Detects keypoints and computes their descriptors.
    fn detect_and_compute(
        &self,
        img: &Plane<u8>,
    ) -> Result<(Vec<Keypoint>, Vec<Self::Descriptor>), CoreError> {
        let kps = self.detect(img)?;
        let d = self.compute(img, &kps)?;
        Ok((kps, d))
    }
}
