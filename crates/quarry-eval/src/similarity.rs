//! How a ground-truth object and a hypothesis are compared: [`Similarity`], [`Iou`] for image
//! boxes and [`Euclidean`] for world-coordinate points.

use quarry_core::{BBox, CoreError};

/// A pairwise comparison of a ground-truth object and a tracker hypothesis.
///
/// Two views of the same comparison are needed, because the two reference tools define them
/// differently:
/// - [`Similarity::distance`] is py-motmetrics' distance (the input of CLEAR MOT and IDF1):
///   `None` when the pair may not be matched (beyond the threshold), otherwise a cost to
///   minimise (`1 - IoU` for boxes, metres for points).
/// - [`Similarity::similarity`] is TrackEval's similarity in `[0, 1]` (the input of HOTA, where
///   every threshold alpha in 0.05..0.95 is applied to it).
pub trait Similarity<T> {
    /// The CLEAR MOT / IDF1 distance, `None` when the pair is beyond the matching threshold.
    fn distance(&self, gt: &T, hyp: &T) -> Option<f64>;
    /// The HOTA similarity in `[0, 1]` (1 = identical).
    fn similarity(&self, gt: &T, hyp: &T) -> f64;
}

/// A box as MOTChallenge files give it: `[left, top, width, height]` in pixels.
pub type Ltwh = [f64; 4];

/// Intersection over union of two `[left, top, width, height]` boxes, computed exactly as
/// py-motmetrics' `boxiou` does (0 when the boxes do not overlap; negative sizes count as 0).
///
/// ```
/// let iou = quarry_eval::similarity::iou_ltwh(&[0.0, 0.0, 10.0, 10.0], &[5.0, 0.0, 10.0, 10.0]);
/// assert!((iou - 1.0 / 3.0).abs() < 1e-15);
/// ```
pub fn iou_ltwh(a: &Ltwh, b: &Ltwh) -> f64 {
    let (ax1, ay1) = (a[0] + a[2], a[1] + a[3]);
    let (bx1, by1) = (b[0] + b[2], b[1] + b[3]);
    let iw = (ax1.min(bx1) - a[0].max(b[0])).max(0.0);
    let ih = (ay1.min(by1) - a[1].max(b[1])).max(0.0);
    let inter = iw * ih;
    if inter == 0.0 {
        return 0.0;
    }
    let a_vol = (ax1 - a[0]).max(0.0) * (ay1 - a[1]).max(0.0);
    let b_vol = (bx1 - b[0]).max(0.0) * (by1 - b[1]).max(0.0);
    inter / (a_vol + b_vol - inter)
}

/// Box overlap: distance `1 - IoU`, allowed while `1 - IoU <= 1 - threshold` (py-motmetrics'
/// `iou_matrix(max_iou = 1 - threshold)`); HOTA similarity = IoU. The MOTChallenge default is
/// `threshold = 0.5`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Iou {
    /// Minimum IoU of a match (0.5 in MOTChallenge).
    pub threshold: f64,
}

impl Iou {
    /// A checked IoU criterion: `threshold` must lie in `(0, 1]`.
    pub fn new(threshold: f64) -> Result<Self, CoreError> {
        if threshold > 0.0 && threshold <= 1.0 {
            Ok(Self { threshold })
        } else {
            Err(CoreError::invalid(
                "iou threshold",
                format!("must lie in (0, 1], got {threshold}"),
            ))
        }
    }
}

impl Default for Iou {
    fn default() -> Self {
        Self { threshold: 0.5 }
    }
}

impl Similarity<Ltwh> for Iou {
    fn distance(&self, gt: &Ltwh, hyp: &Ltwh) -> Option<f64> {
        let d = 1.0 - iou_ltwh(gt, hyp);
        (d <= 1.0 - self.threshold).then_some(d)
    }
    fn similarity(&self, gt: &Ltwh, hyp: &Ltwh) -> f64 {
        iou_ltwh(gt, hyp)
    }
}

impl Similarity<BBox> for Iou {
    fn distance(&self, gt: &BBox, hyp: &BBox) -> Option<f64> {
        self.distance(&gt.to_ltwh(), &hyp.to_ltwh())
    }
    fn similarity(&self, gt: &BBox, hyp: &BBox) -> f64 {
        iou_ltwh(&gt.to_ltwh(), &hyp.to_ltwh())
    }
}

/// Point distance: a match needs `|gt - hyp| <= threshold`; the CLEAR distance is the
/// Euclidean distance (so MOTP is a mean distance, in the points' unit); the HOTA similarity is
/// `max(0, 1 - d / zero_at)`.
///
/// [`Euclidean::new`] sets `zero_at = 2 threshold`, so that HOTA at alpha = 0.5 uses the same
/// threshold as CLEAR MOT (spec 003 §4: 0.5 m threshold, `S(d) = max(0, 1 - d / 1 m)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Euclidean {
    /// Largest distance of a match.
    pub threshold: f64,
    /// Distance at which the HOTA similarity reaches 0.
    pub zero_at: f64,
}

impl Euclidean {
    /// A checked distance criterion with `zero_at = 2 threshold`.
    pub fn new(threshold: f64) -> Result<Self, CoreError> {
        Self::with_zero_at(threshold, 2.0 * threshold)
    }

    /// A checked distance criterion with an explicit HOTA zero-similarity distance.
    pub fn with_zero_at(threshold: f64, zero_at: f64) -> Result<Self, CoreError> {
        if !(threshold.is_finite() && threshold > 0.0) {
            return Err(CoreError::invalid(
                "distance threshold",
                format!("must be finite and > 0, got {threshold}"),
            ));
        }
        if !(zero_at.is_finite() && zero_at > 0.0) {
            return Err(CoreError::invalid(
                "zero_at",
                format!("must be finite and > 0, got {zero_at}"),
            ));
        }
        Ok(Self { threshold, zero_at })
    }
}

impl<const N: usize> Similarity<[f64; N]> for Euclidean {
    fn distance(&self, gt: &[f64; N], hyp: &[f64; N]) -> Option<f64> {
        let d2: f64 = gt.iter().zip(hyp).map(|(a, b)| (a - b) * (a - b)).sum();
        (d2 <= self.threshold * self.threshold).then(|| d2.sqrt())
    }
    fn similarity(&self, gt: &[f64; N], hyp: &[f64; N]) -> f64 {
        let d2: f64 = gt.iter().zip(hyp).map(|(a, b)| (a - b) * (a - b)).sum();
        (1.0 - d2.sqrt() / self.zero_at).max(0.0)
    }
}

impl Similarity<quarry_core::Point2> for Euclidean {
    fn distance(&self, gt: &quarry_core::Point2, hyp: &quarry_core::Point2) -> Option<f64> {
        self.distance(&[gt.x, gt.y], &[hyp.x, hyp.y])
    }
    fn similarity(&self, gt: &quarry_core::Point2, hyp: &quarry_core::Point2) -> f64 {
        self.similarity(&[gt.x, gt.y], &[hyp.x, hyp.y])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iou_cases() {
        let a = [0.0, 0.0, 10.0, 10.0];
        assert_eq!(iou_ltwh(&a, &a), 1.0);
        assert_eq!(iou_ltwh(&a, &[20.0, 0.0, 5.0, 5.0]), 0.0);
        assert!((iou_ltwh(&a, &[0.0, 0.0, 10.0, 5.0]) - 0.5).abs() < 1e-15);
        let s = Iou::default();
        assert_eq!(s.distance(&a, &[0.0, 0.0, 10.0, 5.0]), Some(0.5));
        assert_eq!(s.distance(&a, &[0.0, 0.0, 10.0, 4.0]), None);
        assert!(Iou::new(0.0).is_err());
        assert!(Iou::new(f64::NAN).is_err());
    }

    #[test]
    fn euclidean_cases() {
        let e = Euclidean::new(0.5).unwrap();
        assert_eq!(e.distance(&[0.0, 0.0], &[0.3, 0.4]), Some(0.5));
        assert_eq!(e.distance(&[0.0, 0.0], &[0.3, 0.41]), None);
        assert!((e.similarity(&[0.0, 0.0], &[0.3, 0.4]) - 0.5).abs() < 1e-15);
        assert_eq!(e.similarity(&[0.0, 0.0], &[3.0, 4.0]), 0.0);
        assert!(Euclidean::new(-1.0).is_err());
    }
}
