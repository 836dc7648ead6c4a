//! Reading and writing image files (feature `io`).

use crate::VisionError;
use quarry_core::Plane;
use std::path::Path;

/// Largest image side accepted from a file, in pixels (checked against the header before
/// anything is decoded).
pub const MAX_FILE_SIDE: u32 = 16_384;

/// Most pixels an image file may declare (2^26, 67 Mpx, e.g. 8192 x 8192), checked from its
/// header: 200 MB as 8-bit RGB, 540 MB in the widest format a decoder may produce (16-bit RGBA).
pub const MAX_FILE_PIXELS: u64 = 1 << 26;

/// Most memory one decoded image may take, in bytes (512 MiB: an 8-bit RGB image of about
/// 13 000 x 13 000, a 16-bit depth image of about 16 000 x 16 000). A file declaring more is
/// refused from its header, before the decoder allocates (a 275 KB PNG can declare 16 000 x
/// 16 000 RGB, 768 MB).
pub const MAX_DECODED_BYTES: u64 = 512 << 20;

/// Opens and decodes an image file (PNG, JPEG; the format from its content) with the limits
/// above, and refuses a JPEG that is cut short.
///
/// The JPEG decoder fills the part of a truncated file it never read with grey and reports
/// success; a truncated frame would then be tracked as if half of it were a flat grey wall.
/// A complete JPEG ends its last scan (`SOS`, `FF DA`) with an end-of-image marker (`FF D9`);
/// entropy-coded data cannot contain either (every `FF` in it is stuffed as `FF 00`), so a file
/// without `FF D9` after its last `FF DA` is refused. (An embedded EXIF thumbnail has its own
/// markers, earlier in the file.)
///
/// ```no_run
/// let img = quarry_vision::io::open_image("frame_0001.jpg")?;
/// println!("{} x {}", img.width(), img.height());
/// # Ok::<(), quarry_vision::VisionError>(())
/// ```
pub fn open_image(path: impl AsRef<Path>) -> Result<image::DynamicImage, VisionError> {
    let path = path.as_ref();
    let err = |reason: String| VisionError::Io {
        path: path.display().to_string(),
        reason,
    };
    let bytes = read_bounded(path).map_err(&err)?;
    decode_image(&bytes).map_err(err)
}

/// Reads a file of at most [`MAX_DECODED_BYTES`] (a compressed image is never larger than
/// its decoded pixels would be allowed to be).
fn read_bounded(path: &Path) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut bytes = Vec::new();
    f.take(MAX_DECODED_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > MAX_DECODED_BYTES {
        return Err(format!(
            "the file is larger than {} MiB, more than any image quarry reads",
            MAX_DECODED_BYTES >> 20
        ));
    }
    Ok(bytes)
}

/// [`open_image`] on bytes in memory.
pub fn decode_image(bytes: &[u8]) -> Result<image::DynamicImage, String> {
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    let format = reader.format();
    if format == Some(image::ImageFormat::Jpeg) && !jpeg_is_complete(bytes) {
        return Err(
            "the JPEG is truncated (no end-of-image marker after its last scan): the file was cut short"
                .into(),
        );
    }
    // the header first: a decoder may read (and allocate) further before its own limits apply
    let (w, h) = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?
        .into_dimensions()
        .map_err(|e| e.to_string())?;
    if w > MAX_FILE_SIDE || h > MAX_FILE_SIDE || u64::from(w) * u64::from(h) > MAX_FILE_PIXELS {
        return Err(format!(
            "the image declares {w} x {h} pixels: quarry reads images of at most {MAX_FILE_SIDE} pixels a side and {} Mpx",
            MAX_FILE_PIXELS >> 20
        ));
    }
    let mut reader = reader;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_FILE_SIDE);
    limits.max_image_height = Some(MAX_FILE_SIDE);
    limits.max_alloc = Some(MAX_DECODED_BYTES);
    reader.limits(limits);
    reader.decode().map_err(|e| match e {
        image::ImageError::Limits(l) => format!(
            "{l}: quarry reads images of at most {MAX_FILE_SIDE} pixels a side and {} MiB decoded",
            MAX_DECODED_BYTES >> 20
        ),
        e => e.to_string(),
    })
}

/// Whether a JPEG has an end-of-image marker after its last start-of-scan marker.
fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let Some(sos) = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]) else {
        return false;
    };
    bytes[sos..].windows(2).any(|w| w == [0xFF, 0xD9])
}

/// Reads an image file (PNG, JPEG; [`open_image`]'s limits and checks) and converts it to
/// 8-bit grey.
///
/// Grey files are read as they are (16-bit grey is scaled to 8 bits). Colour files are
/// converted with spec 004's rule `Y = round(0.299 R + 0.587 G + 0.114 B)` (BT.601, OpenCV's
/// `cvtColor` / `IMREAD_GRAYSCALE` weights; [`crate::convert::rgb_to_gray_bt601`]), not with the
/// `image` crate's own luma (BT.709 weights), so that SIFT and the segmentation see the grey
/// levels OpenCV would.
pub fn load_gray(path: impl AsRef<Path>) -> Result<Plane<u8>, VisionError> {
    let path = path.as_ref();
    Ok(to_gray_bt601(&open_image(path)?))
}

/// Any decoded image → 8-bit grey: grey as it is, colour by BT.601 (see [`load_gray`]).
pub(crate) fn to_gray_bt601(img: &image::DynamicImage) -> Plane<u8> {
    if img.color().has_color() {
        crate::convert::rgb_to_gray_bt601(&img.to_rgb8())
    } else {
        Plane::from(img.to_luma8())
    }
}

/// Reads an image file as 8-bit RGB ([`open_image`]'s limits and checks).
pub fn load_rgb(path: impl AsRef<Path>) -> Result<image::RgbImage, VisionError> {
    let path = path.as_ref();
    Ok(open_image(path)?.into_rgb8())
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

    fn encode(img: &image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, format).unwrap();
        out.into_inner()
    }

    fn gradient() -> image::DynamicImage {
        image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(64, 48, |x, y| {
            image::Rgb([(x * 4) as u8, (y * 5) as u8, ((x + y) * 2) as u8])
        }))
    }

    #[test]
    fn a_truncated_jpeg_is_refused_and_a_complete_one_read() {
        let jpg = encode(&gradient(), image::ImageFormat::Jpeg);
        let img = decode_image(&jpg).unwrap();
        assert_eq!((img.width(), img.height()), (64, 48));
        for cut in [jpg.len() - 2, jpg.len() * 3 / 4, jpg.len() / 2] {
            let e = decode_image(&jpg[..cut]).unwrap_err();
            assert!(e.contains("truncated"), "cut at {cut}: {e}");
        }
        // bytes after the end-of-image marker (some cameras pad) are fine
        let mut padded = jpg.clone();
        padded.extend_from_slice(&[0; 100]);
        assert!(decode_image(&padded).is_ok());
    }

    #[test]
    fn a_truncated_png_is_refused() {
        let png = encode(&gradient(), image::ImageFormat::Png);
        assert!(decode_image(&png).is_ok());
        assert!(decode_image(&png[..png.len() / 2]).is_err());
        assert!(decode_image(&png[..png.len() - 5]).is_err());
    }

    /// A PNG (signature, IHDR declaring `w` x `h` RGB, a tiny IDAT, IEND; valid CRCs) whose
    /// pixel data is far too short: the shape of a small file declaring a huge image.
    fn png_header(w: u32, h: u32) -> Vec<u8> {
        let mut out = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];
        let mut ihdr = w.to_be_bytes().to_vec();
        ihdr.extend_from_slice(&h.to_be_bytes());
        ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
        for (kind, data) in [
            (*b"IHDR", ihdr),
            (
                *b"IDAT",
                vec![0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
            ),
            (*b"IEND", vec![]),
        ] {
            out.extend_from_slice(&(data.len() as u32).to_be_bytes());
            let mut body = kind.to_vec();
            body.extend_from_slice(&data);
            out.extend_from_slice(&body);
            out.extend_from_slice(&crc32(&body).to_be_bytes());
        }
        out
    }

    fn crc32(data: &[u8]) -> u32 {
        let mut c = 0xFFFF_FFFFu32;
        for &b in data {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 == 1 {
                    (c >> 1) ^ 0xEDB8_8320
                } else {
                    c >> 1
                };
            }
        }
        !c
    }

    #[test]
    fn an_image_declaring_too_many_pixels_is_refused_from_its_header() {
        for (w, h) in [(100_000, 100_000), (16_000, 16_000), (20_000, 10)] {
            let e = decode_image(&png_header(w, h)).unwrap_err();
            assert!(e.contains("at most"), "{w}x{h}: {e}");
        }
    }

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
