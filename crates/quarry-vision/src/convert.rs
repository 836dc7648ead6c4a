//! Conversions between grey/float planes and `image` buffers.
//!
//! `Plane<u8>` ↔ `GrayImage` and `Plane<f32>` ↔ `ImageBuffer<Luma<f32>>` are `From` impls in
//! quarry-core (feature `image`); this module adds the float conversions and the `image`
//! interop for f64 planes (which have no `image` pixel type: they go through f32 or u8).

use crate::VisionError;
use quarry_core::Plane;

/// u8 → f32 (exact).
pub fn u8_to_f32(p: &Plane<u8>) -> Plane<f32> {
    p.map(|&v| f32::from(v))
}

/// u8 → f64 (exact).
pub fn u8_to_f64(p: &Plane<u8>) -> Plane<f64> {
    p.map(|&v| f64::from(v))
}

/// f32 → f64 (exact).
pub fn f32_to_f64(p: &Plane<f32>) -> Plane<f64> {
    p.map(|&v| f64::from(v))
}

/// f64 → f32 (rounded to nearest).
pub fn f64_to_f32(p: &Plane<f64>) -> Plane<f32> {
    p.map(|&v| v as f32)
}

/// Float → u8: rounds half away from zero and saturates to 0..=255 (as OpenCV's
/// `convertTo(CV_8U)` up to its round-half-even); NaN is an error.
pub fn float_to_u8<T: Copy + Into<f64>>(p: &Plane<T>) -> Result<Plane<u8>, VisionError> {
    let mut data = Vec::with_capacity(p.data.len());
    for &v in &p.data {
        let v: f64 = v.into();
        if v.is_nan() {
            return Err(VisionError::NonFinite("float to u8 conversion"));
        }
        data.push(v.round().clamp(0.0, 255.0) as u8);
    }
    Ok(Plane {
        width: p.width,
        height: p.height,
        data,
    })
}

/// Linear rescale of a float plane so that its minimum maps to 0 and its maximum to 255
/// (a constant plane maps to 0); for display of reliefs.
pub fn normalize_to_u8<T: Copy + Into<f64>>(p: &Plane<T>) -> Result<Plane<u8>, VisionError> {
    let vals: Vec<f64> = p.data.iter().map(|&v| v.into()).collect();
    if vals.iter().any(|v| !v.is_finite()) {
        return Err(VisionError::NonFinite("normalize_to_u8"));
    }
    let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let scale = if hi > lo { 255.0 / (hi - lo) } else { 0.0 };
    Ok(Plane {
        width: p.width,
        height: p.height,
        data: vals
            .iter()
            .map(|v| ((v - lo) * scale).round().clamp(0.0, 255.0) as u8)
            .collect(),
    })
}

#[cfg(feature = "io")]
mod image_interop {
    use super::{Plane, VisionError};
    use image::{DynamicImage, ImageBuffer, Luma};

    /// An f32 grey image of the `image` crate.
    pub type GrayImageF32 = ImageBuffer<Luma<f32>, Vec<f32>>;

    /// f64 plane → f32 grey image.
    pub fn f64_to_image(p: &Plane<f64>) -> GrayImageF32 {
        super::f64_to_f32(p).into()
    }

    /// f32 grey image → f64 plane.
    pub fn image_to_f64(img: &GrayImageF32) -> Plane<f64> {
        let (w, h) = img.dimensions();
        Plane {
            width: w,
            height: h,
            data: img.as_raw().iter().map(|&v| f64::from(v)).collect(),
        }
    }

    /// Any decoded image → f32 grey plane in 0..=255: the 8-bit grey of
    /// [`crate::io::load_gray`] (grey as it is, colour by BT.601), so values equal that
    /// function's.
    pub fn dynamic_to_f32(img: &DynamicImage) -> Plane<f32> {
        super::u8_to_f32(&crate::io::to_gray_bt601(img))
    }

    /// `round(0.299 r + 0.587 g + 0.114 b)`, half away from zero. The sum lies in [0, 255], so
    /// truncating `sum + 0.5` gives the same byte for every one of the 2^24 inputs (tested)
    /// without the call into libm that `f64::round` costs on baseline x86-64 (6 % of a
    /// `quarry video` run's samples before).
    #[inline]
    pub(super) fn bt601(r: u8, g: u8, b: u8) -> u8 {
        let y = 0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b);
        (y + 0.5) as u8
    }

    /// RGB → grey with spec 004's rule `Y = round(0.299 R + 0.587 G + 0.114 B)` (BT.601,
    /// OpenCV's `cvtColor` weights; the `image` crate's own luma uses BT.709).
    pub fn rgb_to_gray_bt601(img: &image::RgbImage) -> Plane<u8> {
        let (w, h) = img.dimensions();
        Plane {
            width: w,
            height: h,
            data: img
                .as_raw()
                .chunks_exact(3)
                .map(|p| bt601(p[0], p[1], p[2]))
                .collect(),
        }
    }

    /// A float plane → 8-bit grey image (rounded, saturated).
    pub fn float_to_gray_image<T: Copy + Into<f64>>(
        p: &Plane<T>,
    ) -> Result<image::GrayImage, VisionError> {
        Ok(super::float_to_u8(p)?.into())
    }
}

#[cfg(feature = "io")]
pub use image_interop::{
    GrayImageF32, dynamic_to_f32, f64_to_image, float_to_gray_image, image_to_f64,
    rgb_to_gray_bt601,
};

#[cfg(test)]
mod tests {
    use super::*;

    /// The truncation in `bt601` is `round` (half away from zero, saturated) on every input.
    #[cfg(feature = "io")]
    #[test]
    fn bt601_is_the_rounded_weighted_sum_for_every_colour() {
        for r in 0..=255u8 {
            for g in 0..=255u8 {
                for b in 0..=255u8 {
                    let y = (0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b))
                        .round()
                        .clamp(0.0, 255.0) as u8;
                    assert_eq!(image_interop::bt601(r, g, b), y, "{r} {g} {b}");
                }
            }
        }
    }

    #[test]
    fn round_trips() {
        let p = Plane::from_fn(5, 4, |x, y| (x * 50 + y) as u8);
        assert_eq!(float_to_u8(&u8_to_f32(&p)).unwrap(), p);
        assert_eq!(float_to_u8(&u8_to_f64(&p)).unwrap(), p);
        let f = Plane::from_vec(3, 1, vec![-3.0f64, 127.5, 300.0]).unwrap();
        assert_eq!(float_to_u8(&f).unwrap().data, vec![0, 128, 255]);
        assert!(float_to_u8(&Plane::new(1, 1, f64::NAN)).is_err());
        let n = normalize_to_u8(&Plane::from_vec(3, 1, vec![1.0f64, 2.0, 3.0]).unwrap()).unwrap();
        assert_eq!(n.data, vec![0, 128, 255]);
    }

    #[cfg(feature = "io")]
    #[test]
    fn image_interop() {
        let p = Plane::from_fn(4, 3, |x, y| f64::from(x) * 0.5 + f64::from(y));
        let img = f64_to_image(&p);
        assert_eq!(img.dimensions(), (4, 3));
        assert_eq!(image_to_f64(&img), p);
        let g = float_to_gray_image(&p).unwrap();
        assert_eq!(g.get_pixel(3, 2).0[0], 4);
        let d = image::DynamicImage::ImageLuma8(g);
        assert_eq!(dynamic_to_f32(&d).get(3, 2), Some(&4.0));
        let rgb = image::RgbImage::from_pixel(2, 1, image::Rgb([255, 0, 0]));
        assert_eq!(rgb_to_gray_bt601(&rgb).data, vec![76, 76]);
    }
}
