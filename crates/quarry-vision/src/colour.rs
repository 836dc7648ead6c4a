//! Colour conversion and hue binning for colour histograms (spec 001 §2.5, "depth-colour" cue).
//!
//! * [`rgb_to_hsv`] / [`rgb_to_hsv_f32`]: the standard hexcone HSV, as OpenCV's `cvtColor(RGB2HSV)`
//!   computes it in floating point. Ranges: `h ∈ [0, 360)` degrees, `s ∈ [0, 1]`, `v ∈ [0, 1]`.
//!   OpenCV's 8-bit output stores `h / 2` (0..180), `s · 255` and `v · 255`; its f32 output uses
//!   exactly these ranges.
//! * [`HueBinner`]: maps a pixel to a histogram bin. Chromatic pixels (`s ≥ s_min` and `v ≥ v_min`)
//!   go to `⌊h · hue_bins / 360⌋`; achromatic ones (grey, dark) go to one of `achromatic_bins` value
//!   bins after the hue bins, `hue_bins + min(achromatic_bins − 1, ⌊achromatic_bins · v⌋)`
//!   (Pérez et al. 2002). With `achromatic_bins = 0` (the paper's literal hue-only histogram)
//!   achromatic pixels get [`HueBinner::NO_BIN`].
//! * [`rgb_to_grey`]: the luma `Y = round(0.299 R + 0.587 G + 0.114 B)` that the LBP cue works on.
//!
//! ```
//! use quarry_vision::colour::{HueBinner, rgb_to_hsv};
//! let hsv = rgb_to_hsv(0, 255, 0);
//! assert_eq!(hsv.h, 120.0);
//! let binner = HueBinner::default(); // 16 hue bins + 4 grey bins
//! assert_eq!(binner.bin([0, 0, 255])?, 10);
//! assert_eq!(binner.bin([128, 128, 128])?, 18); // achromatic, value bin 2
//! # Ok::<(), quarry_vision::VisionError>(())
//! ```

use crate::VisionError;
use quarry_core::{CoreError, Plane};

/// A colour in hexcone HSV: `h ∈ [0, 360)` degrees (0 when the colour is grey), `s ∈ [0, 1]`,
/// `v ∈ [0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hsv {
    /// Hue in degrees, `[0, 360)`. OpenCV's 8-bit images store `h / 2`.
    pub h: f32,
    /// Saturation `(max − min) / max`, 0 when `max = 0`. OpenCV 8-bit: `s · 255`.
    pub s: f32,
    /// Value `max`, scaled to `[0, 1]`. OpenCV 8-bit: `v · 255`.
    pub v: f32,
}

/// Hexcone HSV of an 8-bit RGB pixel (OpenCV's floating-point formula, see the module docs).
#[must_use]
pub fn rgb_to_hsv(r: u8, g: u8, b: u8) -> Hsv {
    hsv_unit(
        f32::from(r) / 255.0,
        f32::from(g) / 255.0,
        f32::from(b) / 255.0,
    )
}

/// Hexcone HSV of a floating-point RGB pixel with channels in `[0, 1]`.
///
/// # Errors
/// [`CoreError::NonFinite`] for NaN / infinite channels, [`CoreError::InvalidParameter`] for channels
/// outside `[0, 1]`.
pub fn rgb_to_hsv_f32(r: f32, g: f32, b: f32) -> Result<Hsv, VisionError> {
    if !(r.is_finite() && g.is_finite() && b.is_finite()) {
        return Err(CoreError::NonFinite {
            what: "rgb_to_hsv_f32 input",
        }
        .into());
    }
    if [r, g, b].iter().any(|c| !(0.0..=1.0).contains(c)) {
        return Err(CoreError::invalid(
            "rgb",
            format!("channels must lie in [0, 1], got ({r}, {g}, {b})"),
        )
        .into());
    }
    Ok(hsv_unit(r, g, b))
}

/// HSV of channels known to be finite and in `[0, 1]`.
fn hsv_unit(r: f32, g: f32, b: f32) -> Hsv {
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let diff = max - min;
    let s = if max > 0.0 { diff / max } else { 0.0 };
    let mut h = if diff <= 0.0 {
        0.0
    } else if max == r {
        60.0 * (g - b) / diff
    } else if max == g {
        120.0 + 60.0 * (b - r) / diff
    } else {
        240.0 + 60.0 * (r - g) / diff
    };
    if h < 0.0 {
        h += 360.0;
    }
    if h >= 360.0 {
        h -= 360.0;
    }
    Hsv { h, s, v: max }
}

/// Luma `Y = round(0.299 R + 0.587 G + 0.114 B)` (round half up), the grey level of spec 001 §2.5.
#[must_use]
pub fn rgb_to_grey(rgb: [u8; 3]) -> u8 {
    let y = 299 * u32::from(rgb[0]) + 587 * u32::from(rgb[1]) + 114 * u32::from(rgb[2]);
    // y ≤ 255 000, so (y + 500) / 1000 ≤ 255.
    u8::try_from((y + 500) / 1000).unwrap_or(u8::MAX)
}

/// Grey image of an interleaved RGB buffer (`width · height · 3` bytes, e.g. `RgbImage::as_raw()`).
///
/// # Errors
/// [`VisionError::EmptyImage`] for a zero-sized image, [`CoreError::DimensionMismatch`] when the
/// buffer length is not `3 · width · height`.
pub fn grey_from_interleaved(
    width: u32,
    height: u32,
    rgb: &[u8],
) -> Result<Plane<u8>, VisionError> {
    check_interleaved(width, height, rgb, "grey_from_interleaved")?;
    let data = rgb
        .chunks_exact(3)
        .map(|p| rgb_to_grey([p[0], p[1], p[2]]))
        .collect();
    Ok(Plane::from_vec(width, height, data)?)
}

fn check_interleaved(
    width: u32,
    height: u32,
    rgb: &[u8],
    what: &'static str,
) -> Result<(), VisionError> {
    if width == 0 || height == 0 {
        return Err(VisionError::EmptyImage {
            what,
            width,
            height,
            min: 1,
        });
    }
    let expected = 3 * width as usize * height as usize;
    if rgb.len() != expected {
        return Err(CoreError::DimensionMismatch {
            what,
            expected,
            got: rgb.len(),
        }
        .into());
    }
    Ok(())
}

/// Maps RGB pixels to colour-histogram bins: hue bins for chromatic pixels, value bins for
/// achromatic ones (see the module docs). Spec 001 default: [`HueBinner::default`] = 16 + 4 bins,
/// `s_min = v_min = 0.15`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HueBinner {
    /// Number of hue bins over `[0°, 360°)`; at least 1.
    pub hue_bins: u8,
    /// Number of value bins for achromatic pixels; 0 drops achromatic pixels ([`HueBinner::NO_BIN`]).
    pub achromatic_bins: u8,
    /// Minimum saturation of a chromatic pixel, in `[0, 1]`.
    pub s_min: f32,
    /// Minimum value of a chromatic pixel, in `[0, 1]`.
    pub v_min: f32,
}

impl Default for HueBinner {
    fn default() -> Self {
        Self {
            hue_bins: 16,
            achromatic_bins: 4,
            s_min: 0.15,
            v_min: 0.15,
        }
    }
}

impl HueBinner {
    /// Bin index of a pixel that has no bin (achromatic with `achromatic_bins = 0`).
    pub const NO_BIN: u8 = u8::MAX;

    /// The paper's literal hue-only binner: 16 hue bins, achromatic pixels dropped.
    #[must_use]
    pub fn hue_only() -> Self {
        Self {
            achromatic_bins: 0,
            ..Self::default()
        }
    }

    /// Total number of bins, `hue_bins + achromatic_bins`.
    #[must_use]
    pub fn n_bins(&self) -> usize {
        usize::from(self.hue_bins) + usize::from(self.achromatic_bins)
    }

    /// Checks the parameters.
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] when `hue_bins = 0`, the total reaches 255 (which is
    /// [`HueBinner::NO_BIN`]), or a threshold is not in `[0, 1]`.
    pub fn validate(&self) -> Result<(), VisionError> {
        if self.hue_bins == 0 {
            return Err(CoreError::invalid("hue_bins", "must be at least 1").into());
        }
        if self.n_bins() >= usize::from(Self::NO_BIN) {
            return Err(
                CoreError::invalid("hue_bins + achromatic_bins", "must be below 255").into(),
            );
        }
        for (name, x) in [("s_min", self.s_min), ("v_min", self.v_min)] {
            if !(0.0..=1.0).contains(&x) {
                return Err(
                    CoreError::invalid(name, format!("must lie in [0, 1], got {x}")).into(),
                );
            }
        }
        Ok(())
    }

    /// Bin of an HSV colour, without validating `self` (callers validate once).
    fn bin_unchecked(&self, c: Hsv) -> u8 {
        if c.s >= self.s_min && c.v >= self.v_min {
            let k = (c.h * f32::from(self.hue_bins) / 360.0).floor();
            // h < 360, but clamp against rounding at the top edge.
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let k = k.max(0.0) as u32;
            u8::try_from(k.min(u32::from(self.hue_bins) - 1)).unwrap_or(0)
        } else if self.achromatic_bins == 0 {
            Self::NO_BIN
        } else {
            let a = (c.v * f32::from(self.achromatic_bins)).floor();
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let a = a.max(0.0) as u32;
            let a = a.min(u32::from(self.achromatic_bins) - 1);
            u8::try_from(u32::from(self.hue_bins) + a).unwrap_or(Self::NO_BIN)
        }
    }

    /// Bin of an HSV colour.
    ///
    /// # Errors
    /// An invalid binner ([`HueBinner::validate`]) or a non-finite / out-of-range colour.
    pub fn bin_hsv(&self, c: Hsv) -> Result<u8, VisionError> {
        self.validate()?;
        if !(c.h.is_finite() && c.s.is_finite() && c.v.is_finite()) {
            return Err(CoreError::NonFinite { what: "hsv colour" }.into());
        }
        if !((0.0..360.0).contains(&c.h)
            && (0.0..=1.0).contains(&c.s)
            && (0.0..=1.0).contains(&c.v))
        {
            return Err(CoreError::invalid("hsv", format!("out of range: {c:?}")).into());
        }
        Ok(self.bin_unchecked(c))
    }

    /// Bin of an 8-bit RGB pixel.
    ///
    /// # Errors
    /// An invalid binner ([`HueBinner::validate`]).
    pub fn bin(&self, rgb: [u8; 3]) -> Result<u8, VisionError> {
        self.validate()?;
        Ok(self.bin_unchecked(rgb_to_hsv(rgb[0], rgb[1], rgb[2])))
    }

    /// Bin-index map of an RGB plane.
    ///
    /// # Errors
    /// An invalid binner, or [`VisionError::EmptyImage`] for a zero-sized plane.
    pub fn bin_map(&self, rgb: &Plane<[u8; 3]>) -> Result<Plane<u8>, VisionError> {
        self.validate()?;
        if rgb.width == 0 || rgb.height == 0 {
            return Err(VisionError::EmptyImage {
                what: "HueBinner::bin_map",
                width: rgb.width,
                height: rgb.height,
                min: 1,
            });
        }
        Ok(rgb.map(|p| self.bin_unchecked(rgb_to_hsv(p[0], p[1], p[2]))))
    }

    /// Bin-index map of an interleaved RGB buffer (`width · height · 3` bytes, e.g.
    /// `RgbImage::as_raw()`).
    ///
    /// # Errors
    /// An invalid binner, [`VisionError::EmptyImage`] for a zero-sized image, or
    /// [`CoreError::DimensionMismatch`] for a buffer of the wrong length.
    pub fn bin_map_interleaved(
        &self,
        width: u32,
        height: u32,
        rgb: &[u8],
    ) -> Result<Plane<u8>, VisionError> {
        self.validate()?;
        check_interleaved(width, height, rgb, "HueBinner::bin_map_interleaved")?;
        let data = rgb
            .chunks_exact(3)
            .map(|p| self.bin_unchecked(rgb_to_hsv(p[0], p[1], p[2])))
            .collect();
        Ok(Plane::from_vec(width, height, data)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn spec_bins() {
        let b = HueBinner::default();
        assert_eq!(b.bin([255, 0, 0]).unwrap(), 0);
        assert_eq!(b.bin([0, 255, 0]).unwrap(), 5);
        assert_eq!(b.bin([0, 0, 255]).unwrap(), 10);
        assert_eq!(b.bin([128, 128, 128]).unwrap(), 18);
        assert_eq!(b.bin([0, 0, 0]).unwrap(), 16);
        assert_eq!(b.bin([255, 255, 255]).unwrap(), 19);
        assert_eq!(
            HueBinner::hue_only().bin([128, 128, 128]).unwrap(),
            HueBinner::NO_BIN
        );
        assert_eq!(HueBinner::hue_only().n_bins(), 16);
    }

    #[test]
    fn hsv_values_match_opencv() {
        // cv2.cvtColor(np.uint8([[[r,g,b]]]) / 255 as f32, RGB2HSV) values.
        let c = rgb_to_hsv(255, 128, 0);
        assert!((c.h - 30.117_647).abs() < 1e-4, "{c:?}");
        assert!((c.s - 1.0).abs() < 1e-6 && (c.v - 1.0).abs() < 1e-6);
        let c = rgb_to_hsv(100, 50, 200);
        assert!((c.h - 260.0).abs() < 1e-4, "{c:?}");
        assert!((c.s - 0.75).abs() < 1e-6);
        assert!((c.v - 200.0 / 255.0).abs() < 1e-6);
        // magenta: negative hue wrapped
        let c = rgb_to_hsv(255, 0, 128);
        assert!((c.h - 329.882_35).abs() < 1e-3, "{c:?}");
        assert_eq!(rgb_to_hsv(7, 7, 7).h, 0.0);
        assert_eq!(rgb_to_hsv(0, 0, 0).s, 0.0);
    }

    #[test]
    fn grey_levels() {
        assert_eq!(rgb_to_grey([255, 255, 255]), 255);
        assert_eq!(rgb_to_grey([255, 0, 0]), 76); // 76.245
        assert_eq!(rgb_to_grey([0, 255, 0]), 150); // 149.685
        assert_eq!(rgb_to_grey([0, 0, 255]), 29); // 29.07
        let g = grey_from_interleaved(2, 1, &[255, 0, 0, 10, 10, 10]).unwrap();
        assert_eq!(g.data, vec![76, 10]);
    }

    #[test]
    fn errors() {
        let bad = HueBinner {
            hue_bins: 0,
            ..HueBinner::default()
        };
        assert!(bad.bin([1, 2, 3]).is_err());
        let bad = HueBinner {
            hue_bins: 200,
            achromatic_bins: 60,
            ..HueBinner::default()
        };
        assert!(bad.validate().is_err());
        let bad = HueBinner {
            s_min: f32::NAN,
            ..HueBinner::default()
        };
        assert!(bad.validate().is_err());
        assert!(rgb_to_hsv_f32(f32::NAN, 0.0, 0.0).is_err());
        assert!(rgb_to_hsv_f32(1.5, 0.0, 0.0).is_err());
        let b = HueBinner::default();
        assert!(b.bin_map_interleaved(2, 2, &[0; 11]).is_err());
        assert!(b.bin_map_interleaved(0, 2, &[]).is_err());
        assert!(b.bin_map(&Plane::new(0, 3, [0u8; 3])).is_err());
        assert!(
            b.bin_hsv(Hsv {
                h: 360.0,
                s: 1.0,
                v: 1.0
            })
            .is_err()
        );
    }

    #[test]
    fn maps_agree() {
        let plane = Plane::from_fn(7, 5, |x, y| {
            [(x * 37) as u8, (y * 51) as u8, ((x + y) * 20) as u8]
        });
        let raw: Vec<u8> = plane.data.iter().flatten().copied().collect();
        let b = HueBinner::default();
        let m1 = b.bin_map(&plane).unwrap();
        let m2 = b.bin_map_interleaved(7, 5, &raw).unwrap();
        assert_eq!(m1, m2);
        for (p, &k) in plane.data.iter().zip(&m1.data) {
            assert_eq!(b.bin(*p).unwrap(), k);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn hsv_ranges_and_bins(r in any::<u8>(), g in any::<u8>(), b in any::<u8>()) {
            let c = rgb_to_hsv(r, g, b);
            prop_assert!((0.0..360.0).contains(&c.h));
            prop_assert!((0.0..=1.0).contains(&c.s));
            prop_assert!((0.0..=1.0).contains(&c.v));
            let k = HueBinner::default().bin([r, g, b]).unwrap();
            prop_assert!(k < 20);
            let chromatic = c.s >= 0.15 && c.v >= 0.15;
            prop_assert_eq!(chromatic, k < 16);
            if r == g && g == b {
                prop_assert!(k >= 16);
            }
        }

        /// Spec 001 §6.1.5: a gain g ∈ [0.5, 1] keeps the hue bin of a pixel with S, V ≥ 0.3.
        #[test]
        fn gain_keeps_hue_bin(r in 0.0f32..=1.0, g in 0.0f32..=1.0, b in 0.0f32..=1.0, gain in 0.5f32..=1.0) {
            let c = rgb_to_hsv_f32(r, g, b).unwrap();
            prop_assume!(c.s >= 0.3 && c.v >= 0.3);
            let edge = c.h * 16.0 / 360.0;
            prop_assume!((edge - edge.round()).abs() * 22.5 > 1e-3);
            let d = rgb_to_hsv_f32(r * gain, g * gain, b * gain).unwrap();
            let binner = HueBinner::default();
            prop_assert_eq!(binner.bin_hsv(c).unwrap(), binner.bin_hsv(d).unwrap());
            prop_assert!(binner.bin_hsv(d).unwrap() < 16);
        }
    }
}
