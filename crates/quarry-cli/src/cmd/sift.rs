//! `quarry sift`: SIFT keypoints of an image, or keypoints and matches of two images.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_hollow_circle_mut, draw_line_segment_mut};
use quarry_core::{Keypoint, Plane};
use quarry_vision::io::load_gray;
use quarry_vision::matching::{BruteForceL2, DMatch, MatchOptions, match_descriptors};
use quarry_vision::sift::{Sift, SiftParams};
use serde::Serialize;

use crate::output::{CmdResult, Output};

/// Arguments of `quarry sift`.
#[derive(Debug, Args)]
#[command(
    about = "SIFT keypoints of an image, or keypoints and matches of two images",
    long_about = "SIFT keypoints of an image (Lowe 2004, OpenCV-compatible: 3 layers per octave, \
sigma 1.6, up-sampled first octave, contrast threshold 0.04, edge threshold 10, 128-byte \
descriptors with L2 norm about 512), or the keypoints of two images and their matches \
(brute-force L2 nearest neighbour, Lowe's ratio test, optional mutual check).

Images: PNG or JPEG, converted to 8-bit grey.

OUTPUT: a summary (keypoint counts, matches, time); with --out FILE.png the image(s) with the \
keypoints drawn as circles of radius 3 sigma and, with two images side by side, the matches as \
lines.

JSON (--json) prints one object with: keypoints (one image: the list of keypoints; two images: \
a list of two lists), each keypoint {x, y, sigma, angle_deg, response, octave, layer, \
layer_offset} in input pixels (OpenCV's KeyPoint.size is 2 sigma); n_keypoints (a number or \
two); ms (detection + description + matching time in milliseconds, excluding image I/O); with \
two images matches: a list of {query, train, distance}, query indexing the first image's \
keypoints.

EXAMPLE:
  quarry sift photo.png --out keypoints.png
  quarry sift frame1.jpg frame2.jpg --out matches.png --json | jq '.matches | length'"
)]
pub struct SiftArgs {
    /// The image.
    #[arg(value_name = "IMAGE")]
    pub image: PathBuf,
    /// A second image to match against the first.
    #[arg(value_name = "IMAGE2")]
    pub image2: Option<PathBuf>,
    /// Write the keypoints (and matches) drawn on the image(s) to this PNG.
    #[arg(long, value_name = "FILE.png")]
    pub out: Option<PathBuf>,
    /// Lowe's ratio for matching (keep if d1 < ratio d2); 1 disables the test.
    #[arg(long, default_value_t = 0.8)]
    pub ratio: f32,
    /// Keep only mutual nearest neighbours.
    #[arg(long)]
    pub mutual: bool,
    /// Keep only matches with a descriptor distance below this (512-norm scale).
    #[arg(long, value_name = "DIST")]
    pub max_distance: Option<f32>,
    /// Do not up-sample the first octave (faster, fewer small keypoints).
    #[arg(long)]
    pub no_upsample: bool,
}

#[derive(Debug, Serialize)]
#[serde(untagged)]
enum KeypointsJson<'a> {
    One(&'a [Keypoint]),
    Two([&'a [Keypoint]; 2]),
}

#[derive(Debug, Serialize)]
#[serde(untagged)]
enum CountJson {
    One(usize),
    Two([usize; 2]),
}

#[derive(Debug, Serialize)]
struct SiftJson<'a> {
    keypoints: KeypointsJson<'a>,
    n_keypoints: CountJson,
    ms: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    matches: Option<&'a [DMatch]>,
}

fn to_rgb(p: &Plane<u8>) -> RgbImage {
    RgbImage::from_fn(p.width, p.height, |x, y| {
        let v = p.get(x, y).copied().unwrap_or(0);
        Rgb([v, v, v])
    })
}

fn draw_keypoints(canvas: &mut RgbImage, kps: &[Keypoint], dx: f32) {
    let colour = Rgb([0u8, 255, 0]);
    for k in kps {
        let (x, y) = (k.x + dx, k.y);
        let r = (3.0 * k.sigma).max(2.0);
        draw_hollow_circle_mut(
            canvas,
            (x.round() as i32, y.round() as i32),
            r.round() as i32,
            colour,
        );
        let a = (-k.angle_deg).to_radians(); // OpenCV's angle is clockwise as displayed
        draw_line_segment_mut(canvas, (x, y), (x + r * a.cos(), y + r * a.sin()), colour);
    }
}

/// Runs `quarry sift`.
pub fn run(args: &SiftArgs, out: &Output) -> CmdResult {
    let sift = Sift::new(SiftParams {
        upsample: !args.no_upsample,
        ..SiftParams::default()
    })?;
    if !(args.ratio.is_finite() && args.ratio > 0.0 && args.ratio <= 1.0) {
        return Err(format!(
            "--ratio {}: must be finite and in (0, 1] (1 disables the test)",
            args.ratio
        )
        .into());
    }
    let opts = MatchOptions {
        ratio: (args.ratio < 1.0).then_some(args.ratio),
        max_distance: args.max_distance,
        mutual: args.mutual,
    };
    opts.validate()?;
    let img1 = load_gray(&args.image)?;
    let img2 = args.image2.as_ref().map(load_gray).transpose()?;
    let t0 = Instant::now();
    let (k1, d1) = sift.extract(&img1)?;
    let second = match &img2 {
        Some(img) => {
            let (k2, d2) = sift.extract(img)?;
            let m = match_descriptors(&BruteForceL2, &d1, &d2, &opts);
            Some((k2, m))
        }
        None => None,
    };
    let ms = t0.elapsed().as_secs_f64() * 1e3;

    if let Some(path) = &args.out {
        let canvas = if let (Some(i2), Some((k2, m))) = (&img2, &second) {
            let (w1, h1) = img1.dimensions();
            let (w2, h2) = i2.dimensions();
            let mut c = RgbImage::new(w1 + w2, h1.max(h2));
            image::imageops::replace(&mut c, &to_rgb(&img1), 0, 0);
            image::imageops::replace(&mut c, &to_rgb(i2), i64::from(w1), 0);
            draw_keypoints(&mut c, &k1, 0.0);
            draw_keypoints(&mut c, k2, w1 as f32);
            for mm in m {
                let (p, q) = (&k1[mm.query], &k2[mm.train]);
                draw_line_segment_mut(
                    &mut c,
                    (p.x, p.y),
                    (q.x + w1 as f32, q.y),
                    Rgb([255u8, 64, 0]),
                );
            }
            c
        } else {
            let mut c = to_rgb(&img1);
            draw_keypoints(&mut c, &k1, 0.0);
            c
        };
        canvas
            .save(path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }

    let json = match &second {
        Some((k2, m)) => SiftJson {
            keypoints: KeypointsJson::Two([&k1, k2]),
            n_keypoints: CountJson::Two([k1.len(), k2.len()]),
            ms,
            matches: Some(m),
        },
        None => SiftJson {
            keypoints: KeypointsJson::One(&k1),
            n_keypoints: CountJson::One(k1.len()),
            ms,
            matches: None,
        },
    };
    out.emit(&json, || {
        let mut s = format!("{}: {} keypoints\n", args.image.display(), k1.len());
        if let (Some(p2), Some((k2, m))) = (&args.image2, &second) {
            let _ = writeln!(
                s,
                "{}: {} keypoints\n{} matches",
                p2.display(),
                k2.len(),
                m.len()
            );
        }
        let _ = writeln!(s, "time: {ms:.1} ms");
        if let Some(p) = &args.out {
            let _ = writeln!(s, "drawn to {}", p.display());
        }
        s
    })
}
