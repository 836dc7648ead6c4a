//! Debug renderings (feature `io`): coloured label images with seeds, trajectories on frames.

use crate::VisionError;
use image::{Rgb, RgbImage};
use quarry_core::{Plane, Segmentation};

/// A stable, well-spread colour for a label (golden-ratio hue walk).
pub fn label_colour(label: u32) -> Rgb<u8> {
    let h = (f64::from(label) * 0.618_033_988_749_895).fract() * 6.0;
    let (s, v) = (0.65, 0.95);
    let i = h.floor();
    let f = h - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let (r, g, b) = match i as u32 {
        0 => (v, t, p),
        1 => (q, v, p),
        2 => (p, v, t),
        3 => (p, q, v),
        4 => (t, p, v),
        _ => (v, p, q),
    };
    Rgb([(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8])
}

/// Paints each region in its colour, darkens region boundaries, and draws every seed
/// (representative minimum) as a black-and-white cross.
pub fn render_labels(seg: &Segmentation) -> Result<RgbImage, VisionError> {
    let (w, h) = seg.labels.dimensions();
    quarry_core::ensure_len(
        seg.labels.data.len(),
        w as usize * h as usize,
        "plane data length (width * height)",
    )?;
    let boundary = crate::watershed::boundary_mask(&seg.labels);
    let mut img = RgbImage::from_fn(w, h, |x, y| {
        let i = y as usize * w as usize + x as usize;
        let c = label_colour(seg.labels.data[i]);
        if boundary.data[i] {
            Rgb([c.0[0] / 2, c.0[1] / 2, c.0[2] / 2])
        } else {
            c
        }
    });
    for m in &seg.minima {
        draw_cross(&mut img, m.representative, 3, Rgb([0, 0, 0]));
        put(
            &mut img,
            i64::from(m.representative.0),
            i64::from(m.representative.1),
            Rgb([255, 255, 255]),
        );
    }
    Ok(img)
}

/// Grey frame → RGB image.
pub fn grey_to_rgb(frame: &Plane<u8>) -> RgbImage {
    RgbImage::from_fn(frame.width, frame.height, |x, y| {
        let v = frame.data[y as usize * frame.width as usize + x as usize];
        Rgb([v, v, v])
    })
}

#[inline]
fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && x < i64::from(img.width()) && y < i64::from(img.height()) {
        img.put_pixel(x as u32, y as u32, c);
    }
}

/// Draws a `+` of half-size `r` (clipped to the image).
pub fn draw_cross(img: &mut RgbImage, at: (u32, u32), r: i64, c: Rgb<u8>) {
    let (x, y) = (i64::from(at.0), i64::from(at.1));
    for d in -r..=r {
        put(img, x + d, y, c);
        put(img, x, y + d, c);
    }
}

/// Draws a line segment (Bresenham, clipped to the image).
pub fn draw_line(img: &mut RgbImage, a: (i64, i64), b: (i64, i64), c: Rgb<u8>) {
    let (mut x, mut y) = a;
    let dx = (b.0 - x).abs();
    let dy = -(b.1 - y).abs();
    let sx = if x < b.0 { 1 } else { -1 };
    let sy = if y < b.1 { 1 } else { -1 };
    let mut err = dx + dy;
    loop {
        put(img, x, y, c);
        if (x, y) == b {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

/// Draws a polyline through `points`.
pub fn draw_polyline(img: &mut RgbImage, points: &[(u32, u32)], c: Rgb<u8>) {
    for w in points.windows(2) {
        draw_line(
            img,
            (i64::from(w[0].0), i64::from(w[0].1)),
            (i64::from(w[1].0), i64::from(w[1].1)),
            c,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use quarry_core::MinimumInfo;

    #[test]
    fn renders() {
        let seg = Segmentation {
            labels: Plane::from_fn(10, 6, |x, _| if x < 5 { 1 } else { 2 }),
            minima: vec![
                MinimumInfo {
                    id: 1,
                    representative: (2, 3),
                    size: 1,
                    value: 0.0,
                },
                MinimumInfo {
                    id: 2,
                    representative: (7, 3),
                    size: 1,
                    value: 0.0,
                },
            ],
        };
        let img = render_labels(&seg).unwrap();
        assert_eq!(img.get_pixel(2, 3).0, [255, 255, 255]);
        assert_eq!(img.get_pixel(2, 2).0, [0, 0, 0]);
        assert_eq!(*img.get_pixel(0, 0), label_colour(1));
        assert_ne!(label_colour(1), label_colour(2));
        let mut canvas = RgbImage::new(5, 5);
        draw_line(&mut canvas, (0, 0), (4, 4), Rgb([9, 9, 9]));
        assert_eq!(canvas.get_pixel(2, 2).0, [9, 9, 9]);
        assert_eq!(canvas.get_pixel(2, 3).0, [0, 0, 0]);
    }
}
