//! Reading and writing image files (feature `io`).

use crate::VisionError;
use quarry_core::Plane;
use std::path::Path;

/// Reads an image file (PNG, JPEG) and converts it to 8-bit grey
/// (`image`'s luma: ITU-R BT.709 weights for colour inputs).
pub fn load_gray(path: impl AsRef<Path>) -> Result<Plane<u8>, VisionError> {
    let path = path.as_ref();
    let img = image::open(path).map_err(|e| VisionError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    Ok(Plane::from(img.into_luma8()))
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
