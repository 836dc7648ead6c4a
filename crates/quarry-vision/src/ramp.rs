//! The regular ramp overlay of spec 004 eqs. (1)–(2).
//!
//! `G(x, y) = x / W + y / H` and `I'(x, y) = (L − 3)/(L − 1) · I(x, y) + 2/(L − 1) · G(x, y)`.
//! One grey level is worth α = (L − 3)/(L − 1) and the whole ramp at most 2β = 4/(L − 1) < α for
//! L > 7, so the order of distinct grey values is preserved while every flat area becomes a
//! plane rising strictly towards +x and +y (its only minimum is its top-left pixel). The result
//! is f64: at 800×450 one horizontal ramp step is 9.8·10⁻⁶, below the f32 spacing at 128–256.

use crate::VisionError;
use quarry_core::{CoreError, Plane};

/// Grey images the ramp accepts (8- and 16-bit).
pub trait GreyLevel: Copy + Into<f64> + Into<u32> {
    /// The largest value of the type: with `levels` above it no pixel needs checking.
    const MAX_LEVEL: u32 = u32::MAX;
}
impl GreyLevel for u8 {
    const MAX_LEVEL: u32 = u8::MAX as u32;
}
impl GreyLevel for u16 {
    const MAX_LEVEL: u32 = u16::MAX as u32;
}

/// The blend coefficients `(α, β) = ((L − 3)/(L − 1), 2/(L − 1))` of eq. (2).
pub fn ramp_coefficients(levels: u32) -> Result<(f64, f64), VisionError> {
    if levels <= 7 {
        return Err(CoreError::invalid(
            "levels",
            format!("the ramp preserves grey order only for L > 7, got {levels}"),
        )
        .into());
    }
    let l = f64::from(levels);
    Ok(((l - 3.0) / (l - 1.0), 2.0 / (l - 1.0)))
}

/// Adds the regular ramp of eqs. (1)–(2) to a grey image with `levels` grey levels
/// (256 for 8-bit video), in f64.
///
/// Errors: an empty image ([`VisionError::EmptyImage`]), `levels <= 7`, or a pixel value
/// `>= levels` (invalid parameter).
pub fn add_regular_ramp<T: GreyLevel>(
    img: &Plane<T>,
    levels: u32,
) -> Result<Plane<f64>, VisionError> {
    let (alpha, beta) = checked_coefficients(img, levels, "regular ramp")?;
    let (w, h) = (img.width as usize, img.height as usize);
    let (gx, gy) = ramp_axes(w, h, beta);
    let mut data = Vec::with_capacity(w * h);
    data.resize(w * h, 0.0);
    for ((row, &ry), out) in img
        .data
        .chunks_exact(w)
        .zip(&gy)
        .zip(data.chunks_exact_mut(w))
    {
        ramp_row(row, alpha, &gx, ry, out);
    }
    Ok(Plane {
        width: img.width,
        height: img.height,
        data,
    })
}

/// Validates a grey image for the ramp (non-empty, consistent, every pixel below `levels`) and
/// returns `(α, β)`.
pub(crate) fn checked_coefficients<T: GreyLevel>(
    img: &Plane<T>,
    levels: u32,
    what: &'static str,
) -> Result<(f64, f64), VisionError> {
    let coefficients = ramp_coefficients(levels)?;
    check_grey(img, what)?;
    // an 8-bit frame with L = 256 cannot hold a pixel >= L: no pass over the pixels
    if levels > T::MAX_LEVEL {
        return Ok(coefficients);
    }
    if let Some(&v) = img.data.iter().find(|&&v| Into::<u32>::into(v) >= levels) {
        return Err(CoreError::invalid(
            "levels",
            format!(
                "pixel value {} is not below L = {levels}",
                Into::<u32>::into(v)
            ),
        )
        .into());
    }
    Ok(coefficients)
}

/// The ramped row `y` of eq. (2), `α I(x, y) + (β x/W + β y/H)`, written into `out` (the exact
/// expression of [`add_regular_ramp`], so fused and materialised ramps are bit-identical).
#[inline]
pub(crate) fn ramp_row<T: GreyLevel>(
    src_row: &[T],
    alpha: f64,
    gx: &[f64],
    ry: f64,
    out: &mut [f64],
) {
    for ((o, &v), &rx) in out.iter_mut().zip(src_row).zip(gx) {
        *o = alpha * Into::<f64>::into(v) + (rx + ry);
    }
}

/// `β x / W` for every column and `β y / H` for every row (the two separable halves of β G).
pub(crate) fn ramp_axes(w: usize, h: usize, beta: f64) -> (Vec<f64>, Vec<f64>) {
    let gx = (0..w).map(|x| beta * (x as f64 / w as f64)).collect();
    let gy = (0..h).map(|y| beta * (y as f64 / h as f64)).collect();
    (gx, gy)
}

pub(crate) fn check_grey<T>(img: &Plane<T>, what: &'static str) -> Result<(), VisionError> {
    if img.width == 0 || img.height == 0 {
        return Err(VisionError::EmptyImage {
            what,
            width: img.width,
            height: img.height,
            min: 1,
        });
    }
    quarry_core::ensure_len(
        img.data.len(),
        img.width as usize * img.height as usize,
        "plane data length (width * height)",
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coefficients_for_8_bit() {
        let (a, b) = ramp_coefficients(256).unwrap();
        assert!((a - 253.0 / 255.0).abs() < 1e-15);
        assert!((b - 2.0 / 255.0).abs() < 1e-15);
        assert!(ramp_coefficients(7).is_err());
    }

    #[test]
    fn values_and_range() {
        let img = Plane::from_fn(800, 450, |x, y| ((x * 7 + y * 3) % 256) as u8);
        let r = add_regular_ramp(&img, 256).unwrap();
        let (a, b) = ramp_coefficients(256).unwrap();
        let v = *r.get(400, 225).unwrap();
        let i = f64::from(*img.get(400, 225).unwrap());
        assert!((v - (a * i + b * (0.5 + 0.5))).abs() < 1e-12);
        assert!(r.data.iter().all(|&v| (0.0..253.0157).contains(&v)));
        let flat = add_regular_ramp(&Plane::new(800, 450, 255u8), 256).unwrap();
        let max = flat.data.iter().copied().fold(f64::MIN, f64::max);
        assert!(max < 253.0157 && max > 253.015);
    }

    #[test]
    fn bad_input() {
        assert!(add_regular_ramp(&Plane::new(0, 0, 0u8), 256).is_err());
        assert!(add_regular_ramp(&Plane::new(3, 3, 200u8), 100).is_err());
        assert!(add_regular_ramp(&Plane::new(3, 3, 1000u16), 65536).is_ok());
    }
}
