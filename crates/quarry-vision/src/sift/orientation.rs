//! Orientation assignment: the smoothed 36-bin gradient-orientation histogram around a refined
//! extremum (OpenCV's `calcOrientationHist`) and one keypoint per histogram peak of at least
//! 0.8 × the maximum, with the peak position interpolated by a parabola.

use super::extrema::Refined;
use super::scale_space::ScaleSpace;
use super::util::{cv_round, fast_atan2, fast_exp, touch_window};
use crate::simd::{isa, multiversion};
use quarry_core::{Keypoint, Plane};

const ORI_HIST_BINS: usize = 36;
const ORI_SIG_FCTR: f32 = 1.5;
const ORI_RADIUS: f32 = 4.5;
const ORI_PEAK_RATIO: f32 = 0.8;

/// The smoothed 36-bin orientation histogram around (c, r) (OpenCV's `calcOrientationHist`);
/// returns its maximum.
#[allow(clippy::inline_always)]
#[inline(always)]
fn orientation_hist_body(
    img: &Plane<f32>,
    r0: usize,
    c0: usize,
    radius: i32,
    sigma: f32,
    hist: &mut [f32; ORI_HIST_BINS],
) -> f32 {
    let w = img.width as i32;
    let h = img.height as i32;
    let n = ORI_HIST_BINS;
    let expf_scale = -1.0 / (2.0 * sigma * sigma);
    let mut raw = [0f32; ORI_HIST_BINS];
    let d = &img.data;
    // Row by row over the window's columns inside the image without its outer ring (a
    // contiguous run): gather, evaluate exp/atan2/sqrt over the run (vectorised), accumulate
    // in OpenCV's order (row-major).
    let jmin = (-radius).max(1 - c0 as i32);
    let jmax = radius.min(w - 2 - c0 as i32);
    if jmin <= jmax {
        let (c, r) = (c0 as i32, r0 as i32);
        touch_window(
            d,
            w as usize,
            c + jmin - 1,
            c + jmax + 1,
            r - radius - 1,
            r + radius + 1,
            h,
        );
        let len = (jmax - jmin + 1) as usize;
        let mut gx = [0f32; ORI_RUN];
        let mut gy = [0f32; ORI_RUN];
        let mut gw = [0f32; ORI_RUN];
        let wu = w as usize;
        for i in -radius..=radius {
            let y = r0 as i32 + i;
            if y <= 0 || y >= h - 1 {
                continue;
            }
            let row0 = (y * w + c0 as i32 + jmin) as usize;
            // Runs longer than the stack buffers are split (same order of accumulation).
            let mut off = 0;
            while off < len {
                let m = (len - off).min(ORI_RUN);
                let at = row0 + off;
                let (right, left) = (&d[at + 1..at + 1 + m], &d[at - 1..at - 1 + m]);
                let (up, down) = (&d[at - wu..at - wu + m], &d[at + wu..at + wu + m]);
                for (((o, &a), &b), (p, (&u, &v))) in gx[..m]
                    .iter_mut()
                    .zip(right)
                    .zip(left)
                    .zip(gy[..m].iter_mut().zip(up.iter().zip(down)))
                {
                    *o = a - b;
                    *p = u - v;
                }
                let j0 = jmin + off as i32;
                for (k, g) in gw[..m].iter_mut().enumerate() {
                    let j = j0 + k as i32;
                    *g = ((i * i + j * j) as f32) * expf_scale;
                }
                for ((wgt, dx), &dy) in gw[..m].iter_mut().zip(gx[..m].iter_mut()).zip(&gy[..m]) {
                    let gdx = *dx;
                    *dx = fast_atan2(dy, gdx) * (n as f32 / 360.0);
                    *wgt = fast_exp(*wgt) * (gdx * gdx + dy * dy).sqrt();
                }
                for (&o, &m) in gx[..m].iter().zip(&gw[..m]) {
                    let mut bin = cv_round(o);
                    if bin >= n as i32 {
                        bin -= n as i32;
                    }
                    if bin < 0 {
                        bin += n as i32;
                    }
                    raw[bin as usize] += m;
                }
                off += m;
            }
        }
    }
    let mut maxval = 0f32;
    for i in 0..n {
        let at = |k: isize| raw[k.rem_euclid(n as isize) as usize];
        let ii = i as isize;
        hist[i] = (at(ii - 2) + at(ii + 2)) * (1.0 / 16.0)
            + (at(ii - 1) + at(ii + 1)) * (4.0 / 16.0)
            + raw[i] * (6.0 / 16.0);
        maxval = maxval.max(hist[i]);
    }
    maxval
}

/// Longest run of window columns processed at once by the orientation histogram.
const ORI_RUN: usize = 128;

multiversion!(avx512, avx2: fn orientation_hist => orientation_hist_body(
    img: &Plane<f32>,
    r0: usize,
    c0: usize,
    radius: i32,
    sigma: f32,
    hist: &mut [f32; ORI_HIST_BINS],
) -> f32);

/// The keypoints (one per orientation peak) of a refined extremum.
pub(super) fn orient(ss: &ScaleSpace, rf: &Refined, out: &mut Vec<Keypoint>) {
    let n = ORI_HIST_BINS;
    let img = &ss.octaves[rf.octave].gauss[rf.layer];
    // σ in octave pixels: size·0.5 / 2^octave with the internal octave index.
    let scl_octv = rf.kp.sigma * 2f32.powi(-(rf.kp.octave));
    let mut hist = [0f32; ORI_HIST_BINS];
    let omax = orientation_hist(
        isa(),
        img,
        rf.r,
        rf.c,
        cv_round(ORI_RADIUS * scl_octv),
        ORI_SIG_FCTR * scl_octv,
        &mut hist,
    );
    let mag_thr = omax * ORI_PEAK_RATIO;
    for j in 0..n {
        let l = if j > 0 { j - 1 } else { n - 1 };
        let r2 = if j < n - 1 { j + 1 } else { 0 };
        if hist[j] > hist[l] && hist[j] > hist[r2] && hist[j] >= mag_thr {
            let mut bin =
                j as f32 + 0.5 * (hist[l] - hist[r2]) / (hist[l] - 2.0 * hist[j] + hist[r2]);
            if bin < 0.0 {
                bin += n as f32;
            } else if bin >= n as f32 {
                bin -= n as f32;
            }
            let mut angle = 360.0 - (360.0 / n as f32) * bin;
            if (angle - 360.0).abs() < f32::EPSILON {
                angle = 0.0;
            }
            out.push(Keypoint {
                angle_deg: angle,
                ..rf.kp
            });
        }
    }
}
