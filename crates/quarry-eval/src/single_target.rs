//! Single-target tracking measures (OTB protocol, Wu et al. 2013), shared by trackers that
//! follow one object: centre location error, precision at a pixel threshold, IoU success curve
//! and its area under the curve.
//!
//! Frames where the tracker gave no box count as failures: IoU 0 and an infinite centre error.
//!
//! ```
//! use quarry_core::BBox;
//! use quarry_eval::single_target::{auc, centre_errors, overlaps, precision_at, success_curve, OTB_THRESHOLDS};
//! let gt = [BBox::from_ltwh(0.0, 0.0, 10.0, 10.0); 3];
//! let out = [Some(BBox::from_ltwh(1.0, 0.0, 10.0, 10.0)), None, Some(gt[2])];
//! let e = centre_errors(&out, &gt)?;
//! assert_eq!(precision_at(&e, 20.0)?, 2.0 / 3.0);
//! let curve = success_curve(&overlaps(&out, &gt)?, &OTB_THRESHOLDS)?;
//! assert_eq!(curve[0], 2.0 / 3.0);         // IoU > 0
//! assert!((auc(&curve)? - 37.0 / 63.0).abs() < 1e-12); // (17 + 20) / 3 / 21
//! # Ok::<(), quarry_eval::EvalError>(())
//! ```

use quarry_core::{BBox, CoreError};

use crate::EvalError;

/// The OTB overlap thresholds 0, 0.05, ..., 1 (21 values).
pub const OTB_THRESHOLDS: [f64; 21] = [
    0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8,
    0.85, 0.9, 0.95, 1.0,
];

/// Distance between the box centres, pixels.
pub fn centre_error(estimate: &BBox, truth: &BBox) -> f64 {
    (estimate.cx - truth.cx).hypot(estimate.cy - truth.cy)
}

/// Intersection over union of two boxes.
pub fn iou(estimate: &BBox, truth: &BBox) -> f64 {
    estimate.iou(truth)
}

fn check_series(out: &[Option<BBox>], gt: &[BBox]) -> Result<(), EvalError> {
    quarry_core::ensure_len(out.len(), gt.len(), "tracker boxes vs ground truth")?;
    if gt.is_empty() {
        return Err(CoreError::Empty {
            what: "ground truth",
        }
        .into());
    }
    quarry_core::ensure_finite(
        gt.iter()
            .flat_map(|b| [b.cx, b.cy, b.w, b.h])
            .collect::<Vec<_>>()
            .iter(),
        "ground-truth boxes",
    )?;
    quarry_core::ensure_finite(
        out.iter()
            .flatten()
            .flat_map(|b| [b.cx, b.cy, b.w, b.h])
            .collect::<Vec<_>>()
            .iter(),
        "tracker boxes",
    )?;
    Ok(())
}

/// Centre error of each frame; `f64::INFINITY` where the tracker gave no box.
pub fn centre_errors(out: &[Option<BBox>], gt: &[BBox]) -> Result<Vec<f64>, EvalError> {
    check_series(out, gt)?;
    Ok(out
        .iter()
        .zip(gt)
        .map(|(o, g)| o.map_or(f64::INFINITY, |o| centre_error(&o, g)))
        .collect())
}

/// IoU of each frame; 0 where the tracker gave no box.
pub fn overlaps(out: &[Option<BBox>], gt: &[BBox]) -> Result<Vec<f64>, EvalError> {
    check_series(out, gt)?;
    Ok(out
        .iter()
        .zip(gt)
        .map(|(o, g)| o.map_or(0.0, |o| o.iou(g)))
        .collect())
}

/// Fraction of frames whose centre error is at most `threshold` pixels (OTB precision; 20 px
/// is the usual threshold).
pub fn precision_at(errors: &[f64], threshold: f64) -> Result<f64, EvalError> {
    if errors.is_empty() {
        return Err(CoreError::Empty {
            what: "error series",
        }
        .into());
    }
    if errors.iter().any(|e| e.is_nan()) {
        return Err(CoreError::NonFinite {
            what: "error series",
        }
        .into());
    }
    if threshold.is_nan() {
        return Err(CoreError::invalid("threshold", "must not be NaN").into());
    }
    Ok(errors.iter().filter(|&&e| e <= threshold).count() as f64 / errors.len() as f64)
}

/// Success curve: for each threshold, the fraction of frames whose IoU is **greater** than it
/// (OTB convention, so the value at threshold 0 is the fraction of frames with any overlap).
pub fn success_curve(ious: &[f64], thresholds: &[f64]) -> Result<Vec<f64>, EvalError> {
    if ious.is_empty() {
        return Err(CoreError::Empty { what: "IoU series" }.into());
    }
    quarry_core::ensure_finite(ious, "IoU series")?;
    quarry_core::ensure_finite(thresholds, "thresholds")?;
    let n = ious.len() as f64;
    Ok(thresholds
        .iter()
        .map(|&t| ious.iter().filter(|&&i| i > t).count() as f64 / n)
        .collect())
}

/// Area under a success curve sampled at evenly spaced thresholds: the mean of its values (the
/// OTB "AUC").
pub fn auc(curve: &[f64]) -> Result<f64, EvalError> {
    if curve.is_empty() {
        return Err(CoreError::Empty {
            what: "success curve",
        }
        .into());
    }
    quarry_core::ensure_finite(curve, "success curve")?;
    Ok(curve.iter().sum::<f64>() / curve.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn success_and_precision() {
        let g = BBox::from_ltwh(0.0, 0.0, 10.0, 10.0);
        let out = [
            Some(g),
            Some(BBox::from_ltwh(5.0, 0.0, 10.0, 10.0)), // IoU 1/3, centre error 5
            None,
            Some(BBox::from_ltwh(30.0, 0.0, 10.0, 10.0)), // no overlap, error 30
        ];
        let gt = [g; 4];
        let e = centre_errors(&out, &gt).unwrap();
        assert_eq!(e[..2], [0.0, 5.0]);
        assert!(e[2].is_infinite());
        assert_eq!(precision_at(&e, 20.0).unwrap(), 0.5);
        let o = overlaps(&out, &gt).unwrap();
        let c = success_curve(&o, &[0.0, 0.3, 0.5, 1.0]).unwrap();
        assert_eq!(c, vec![0.5, 0.5, 0.25, 0.0]);
        let full = success_curve(&o, &OTB_THRESHOLDS).unwrap();
        // 1/3 exceeds 7 thresholds (0..0.30), 1.0 exceeds 20 thresholds: (7 + 20) / 4 / 21
        assert!((auc(&full).unwrap() - 27.0 / 84.0).abs() < 1e-12);
        assert!(centre_errors(&out[..1], &gt).is_err());
        assert!(auc(&[]).is_err());
    }
}
