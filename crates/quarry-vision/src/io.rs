//! Reading and writing image files (feature `io`).

use crate::VisionError;
use quarry_core::Plane;
use std::path::Path;

/// Reads an image file (PNG, JPEG) and converts it to 8-bit grey.
///
/// Grey files are read as they are (16-bit grey is scaled to 8 bits). Colour files are
/// converted with spec 004's rule `Y = round(0.299 R + 0.587 G + 0.114 B)` (BT.601, OpenCV's
/// `cvtColor` / `IMREAD_GRAYSCALE` weights; [`crate::convert::rgb_to_gray_bt601`]), not with the
/// `image` crate's own luma (BT.709 weights), so that SIFT and the segmentation see the grey
/// levels OpenCV would.
pub fn load_gray(path: impl AsRef<Path>) -> Result<Plane<u8>, VisionError> {
    let path = path.as_ref();
    let img = image::open(path).map_err(|e| VisionError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    Ok(to_gray_bt601(&img))
}

/// Any decoded image → 8-bit grey: grey as it is, colour by BT.601 (see [`load_gray`]).
pub(crate) fn to_gray_bt601(img: &image::DynamicImage) -> Plane<u8> {
    if img.color().has_color() {
        crate::convert::rgb_to_gray_bt601(&img.to_rgb8())
    } else {
        Plane::from(img.to_luma8())
    }
}

/// Reads an image file as 8-bit RGB.
pub fn load_rgb(path: impl AsRef<Path>) -> Result<image::RgbImage, VisionError> {
    let path = path.as_ref();
    let img = image::open(path).map_err(|e| VisionError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    Ok(img.into_rgb8())
}

/// Writes an 8-bit grey plane as an image file (format from the extension).
pub fn save_gray(plane: &Plane<u8>, path: impl AsRef<Path>) -> Result<(), VisionError> {
    let path = path.as_ref();
    let img: image::GrayImage = plane.clone().into();
    img.save(path).map_err(|e| VisionError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_files_are_converted_with_bt601_weights() {
        let dir = std::env::temp_dir().join(format!("quarry-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rgb.png");
        // Pure red, green, blue and a mixed pixel: BT.601 gives 76, 150, 29, 128; BT.709
        // (the `image` crate's luma) would give 54, 182, 18.
        let img =
            image::RgbImage::from_raw(4, 1, vec![255, 0, 0, 0, 255, 0, 0, 0, 255, 100, 150, 120])
                .unwrap();
        img.save(&path).unwrap();
        let grey = load_gray(&path).unwrap();
        let expect = |r: f64, g: f64, b: f64| (0.299 * r + 0.587 * g + 0.114 * b).round() as u8;
        assert_eq!(
            grey.data,
            vec![76, 150, 29, expect(100.0, 150.0, 120.0)],
            "BT.601 grey levels"
        );
        // A grey file is read unchanged.
        let g = image::GrayImage::from_raw(2, 1, vec![7, 200]).unwrap();
        let gpath = dir.join("grey.png");
        g.save(&gpath).unwrap();
        assert_eq!(load_gray(&gpath).unwrap().data, vec![7, 200]);
        std::fs::remove_dir_all(&dir).ok();
        assert!(matches!(
            load_gray(dir.join("missing.png")),
            Err(VisionError::Io { .. })
        ));
    }
}
