//! The SIFT descriptor (OpenCV's `calcSIFTDescriptor`): gradient samples of a rotated window
//! around the keypoint, Gaussian-weighted and split trilinearly into 4×4 cells × 8 orientation
//! bins; the 0.2 clamp with renormalisation ([`normalize_descriptor`]) and the quantisation to
//! bytes ([`quantize`]).

use super::scale_space::ScaleSpace;
use super::util::{cv_round, fast_atan2, fast_exp, floor_small, touch_window};
use super::{DESCRIPTOR_LEN, SiftDescriptor};
use crate::VisionError;
use crate::simd::{isa, multiversion};
use quarry_core::{CoreError, Keypoint, Plane};

#[cfg(feature = "parallel")]
use rayon::prelude::*;

const DESCR_WIDTH: usize = 4;
const DESCR_HIST_BINS: usize = 8;
const DESCR_SCL_FCTR: f32 = 3.0;
const DESCR_MAG_THR: f32 = 0.2;
const INT_DESCR_FCTR: f32 = 512.0;

/// Unit-norm float descriptors (after the 0.2 clamp and renormalisation, before quantisation)
/// of the keypoints `kps` in scale space `ss` ([`super::Sift::describe_in`]).
pub(super) fn describe(
    ss: &ScaleSpace,
    kps: &[Keypoint],
) -> Result<Vec<[f32; DESCRIPTOR_LEN]>, VisionError> {
    // Check every keypoint first, so the (parallel) computation cannot fail.
    let mut jobs = Vec::with_capacity(kps.len());
    for kp in kps {
        jobs.push(descriptor_job(ss, kp)?);
    }
    let level = isa();
    let run = |sc: &mut DescScratch,
               &(o, layer, x, y, ori, scl): &(usize, usize, f32, f32, f32, f32)| {
        let img = &ss.octaves[o].gauss[layer];
        let mut v = raw_descriptor(level, img, x, y, ori, scl, sc);
        normalize_descriptor(&mut v);
        v
    };
    #[cfg(feature = "parallel")]
    let out = jobs
        .par_iter()
        .with_min_len(16)
        .map_init(DescScratch::default, run)
        .collect();
    #[cfg(not(feature = "parallel"))]
    let out = {
        let mut sc = DescScratch::default();
        jobs.iter().map(|j| run(&mut sc, j)).collect()
    };
    Ok(out)
}

type DescriptorJob = (usize, usize, f32, f32, f32, f32);

/// Where and how to compute the descriptor of `kp`: (internal octave, layer, x, y in octave
/// pixels, y-up orientation in degrees, σ in octave pixels).
fn descriptor_job(ss: &ScaleSpace, kp: &Keypoint) -> Result<DescriptorJob, VisionError> {
    let finite =
        kp.x.is_finite() && kp.y.is_finite() && kp.sigma.is_finite() && kp.angle_deg.is_finite();
    if !finite || kp.sigma <= 0.0 {
        return Err(VisionError::NonFinite("keypoint (x, y, sigma, angle)"));
    }
    let o = kp.octave - ss.first_octave;
    if o < 0 || o as usize >= ss.octaves.len() {
        return Err(CoreError::invalid(
            "keypoint octave",
            format!(
                "{} outside the scale space's octaves {}..{}",
                kp.octave,
                ss.first_octave,
                ss.first_octave + ss.octaves.len() as i32
            ),
        )
        .into());
    }
    if kp.layer < 0 || kp.layer as usize >= ss.layers + 3 {
        return Err(CoreError::invalid(
            "keypoint layer",
            format!("{} outside 0..{}", kp.layer, ss.layers + 3),
        )
        .into());
    }
    let scale = 2f32.powi(-kp.octave);
    let mut ori = 360.0 - kp.angle_deg;
    if (ori - 360.0).abs() < f32::EPSILON {
        ori = 0.0;
    }
    let x = kp.x * scale;
    let y = kp.y * scale;
    if x.abs() > 1e7 || y.abs() > 1e7 {
        return Err(CoreError::invalid("keypoint position", "far outside the image").into());
    }
    Ok((
        o as usize,
        kp.layer as usize,
        x,
        y,
        ori,
        kp.sigma * 2.0 * scale * 0.5,
    ))
}

/// Per-worker scratch of the descriptor: gathered samples (structure of arrays), flushed into
/// the histogram in chunks so that memory stays bounded for any keypoint size.
#[derive(Default)]
struct DescScratch {
    dx: Vec<f32>,
    dy: Vec<f32>,
    rbin: Vec<f32>,
    cbin: Vec<f32>,
    w: Vec<f32>,
}

/// Samples gathered before they are accumulated (the order of accumulation is the gathering
/// order, so chunking does not change the sums).
const DESC_CHUNK: usize = 1024;

/// Samples whose trilinear weights are computed together (vectorised) before being scattered.
const DESC_BLOCK: usize = 16;

impl DescScratch {
    fn ensure(&mut self, n: usize) {
        for v in [
            &mut self.dx,
            &mut self.dy,
            &mut self.rbin,
            &mut self.cbin,
            &mut self.w,
        ] {
            if v.len() < n {
                v.resize(n, 0.0);
            }
        }
    }
}

/// The raw 128-bin histogram (OpenCV's `calcSIFTDescriptor` before normalisation).
///
/// The samples of one window row that pass OpenCV's per-sample test
/// (`-1 < rbin < d`, `-1 < cbin < d`, inside the image without its outer pixel ring) form one
/// contiguous run of columns: `rbin` and `cbin` are monotone in the column (IEEE rounding of a
/// product with a fixed factor and of a sum with a fixed term are monotone), so each test holds
/// on an interval. The run's ends are found with the per-sample test itself, and the run is
/// processed with whole-slice loops that vectorise; the samples, their values and the order in
/// which they are accumulated are exactly OpenCV's (and the previous scalar loop's).
#[allow(clippy::inline_always)]
#[inline(always)]
fn raw_descriptor_body(
    img: &Plane<f32>,
    ptx: f32,
    pty: f32,
    ori: f32,
    scl: f32,
    sc: &mut DescScratch,
) -> [f32; DESCRIPTOR_LEN] {
    const D: usize = DESCR_WIDTH;
    const N: usize = DESCR_HIST_BINS;
    let px = cv_round(ptx);
    let py = cv_round(pty);
    let rad = ori * (std::f32::consts::PI / 180.0);
    let mut cos_t = rad.cos();
    let mut sin_t = rad.sin();
    let bins_per_rad = N as f32 / 360.0;
    let exp_scale = -1.0 / (D as f32 * D as f32 * 0.5);
    let hist_width = DESCR_SCL_FCTR * scl;
    let rows = img.height as i32;
    let cols = img.width as i32;
    let diag =
        (f64::from(cols) * f64::from(cols) + f64::from(rows) * f64::from(rows)).sqrt() as i32;
    let radius = cv_round(hist_width * std::f32::consts::SQRT_2 * (D as f32 + 1.0) * 0.5).min(diag);
    cos_t /= hist_width;
    sin_t /= hist_width;
    let mut hist = [0f32; (D + 2) * (D + 2) * (N + 2)];
    let data = &img.data;
    let half = D as f32 / 2.0 - 0.5;
    // Columns j of the window inside the image without its outer ring: 0 < px + j < cols − 1.
    let jmin = (-radius).max(1 - px);
    let jmax = radius.min(cols - 2 - px);
    let run_max = (jmax - jmin + 1).max(0) as usize;
    sc.ensure(DESC_CHUNK + run_max + DESC_BLOCK);
    if jmin <= jmax {
        touch_window(
            data,
            cols as usize,
            px + jmin - 1,
            px + jmax + 1,
            py - radius - 1,
            py + radius + 1,
            rows,
        );
    }
    let mut n = 0usize;
    for i in -radius..=radius {
        let r = py + i;
        if r <= 0 || r >= rows - 1 || jmin > jmax {
            continue;
        }
        let fi = i as f32;
        let inside = |j: i32| -> bool {
            let fj = j as f32;
            let c_rot = fj * cos_t - fi * sin_t;
            let r_rot = fj * sin_t + fi * cos_t;
            let rbin = r_rot + half;
            let cbin = c_rot + half;
            rbin > -1.0 && rbin < D as f32 && cbin > -1.0 && cbin < D as f32
        };
        let mut lo = jmin;
        while lo <= jmax && !inside(lo) {
            lo += 1;
        }
        if lo > jmax {
            continue;
        }
        let mut hi = jmax;
        while !inside(hi) {
            hi -= 1;
        }
        let len = (hi - lo + 1) as usize;
        let row = (r * cols) as usize;
        let c0 = (px + lo) as usize;
        let cu = cols as usize;
        let mid = &data[row + c0..row + c0 + len];
        let left = &data[row + c0 - 1..row + c0 - 1 + len];
        let right = &data[row + c0 + 1..row + c0 + 1 + len];
        let up = &data[row + c0 - cu..row + c0 - cu + len];
        let down = &data[row + c0 + cu..row + c0 + cu + len];
        let _ = mid;
        for ((o, &a), &b) in sc.dx[n..n + len].iter_mut().zip(right).zip(left) {
            *o = a - b;
        }
        for ((o, &a), &b) in sc.dy[n..n + len].iter_mut().zip(up).zip(down) {
            *o = a - b;
        }
        let fisin = fi * sin_t;
        let ficos = fi * cos_t;
        for (k, ((rb, cb), wt)) in sc.rbin[n..n + len]
            .iter_mut()
            .zip(&mut sc.cbin[n..n + len])
            .zip(&mut sc.w[n..n + len])
            .enumerate()
        {
            let fj = (lo + k as i32) as f32;
            let c_rot = fj * cos_t - fisin;
            let r_rot = fj * sin_t + ficos;
            *rb = r_rot + half;
            *cb = c_rot + half;
            *wt = (c_rot * c_rot + r_rot * r_rot) * exp_scale;
        }
        n += len;
        if n >= DESC_CHUNK {
            accumulate_descriptor(sc, n, ori, bins_per_rad, &mut hist);
            n = 0;
        }
    }
    accumulate_descriptor(sc, n, ori, bins_per_rad, &mut hist);
    let mut dst = [0f32; DESCRIPTOR_LEN];
    for i in 0..D {
        for j in 0..D {
            let idx = ((i + 1) * (D + 2) + (j + 1)) * (N + 2);
            hist[idx] += hist[idx + N];
            hist[idx + 1] += hist[idx + N + 1];
            dst[(i * D + j) * N..(i * D + j + 1) * N].copy_from_slice(&hist[idx..idx + N]);
        }
    }
    dst
}

multiversion!(avx512, avx2: fn raw_descriptor => raw_descriptor_body(
    img: &Plane<f32>,
    ptx: f32,
    pty: f32,
    ori: f32,
    scl: f32,
    sc: &mut DescScratch,
) -> [f32; DESCRIPTOR_LEN]);

/// Accumulates the first `n` gathered samples of `sc` into the descriptor histogram
/// (orientation, magnitude, Gaussian weight, then OpenCV's trilinear split), in order.
#[allow(clippy::inline_always)]
#[inline(always)]
fn accumulate_descriptor(
    sc: &mut DescScratch,
    n: usize,
    ori: f32,
    bins_per_rad: f32,
    hist: &mut [f32; (DESCR_WIDTH + 2) * (DESCR_WIDTH + 2) * (DESCR_HIST_BINS + 2)],
) {
    const D: usize = DESCR_WIDTH;
    const N: usize = DESCR_HIST_BINS;
    const B: usize = DESC_BLOCK;
    // Orientation into `dx`, weighted magnitude into `dy` (in place, vectorisable).
    for ((dx, dy), &w) in sc.dx[..n]
        .iter_mut()
        .zip(sc.dy[..n].iter_mut())
        .zip(&sc.w[..n])
    {
        let (gx, gy) = (*dx, *dy);
        *dx = fast_atan2(gy, gx);
        *dy = (gx * gx + gy * gy).sqrt() * fast_exp(w);
    }
    let rs = (D + 2) * (N + 2);
    let mut start = 0;
    while start < n {
        // Weights of a whole block of B samples (lanes past `n` hold stale values and are not
        // scattered), then the scatter of the `m` real ones, in order.
        let m = (n - start).min(B);
        let mut idx = [0usize; B];
        let mut v = [[0f32; B]; 8];
        let (ori_v, mag_v) = (&sc.dx[start..start + B], &sc.dy[start..start + B]);
        let (rb_v, cb_v) = (&sc.rbin[start..start + B], &sc.cbin[start..start + B]);
        for k in 0..B {
            let (rbin, cbin, mag) = (rb_v[k], cb_v[k], mag_v[k]);
            let obin = (ori_v[k] - ori) * bins_per_rad;
            let r0 = floor_small(rbin);
            let c0 = floor_small(cbin);
            let o0f = floor_small(obin);
            let (rf, cf, of) = (rbin - r0, cbin - c0, obin - o0f);
            let (r0, c0) = (r0 as i32, c0 as i32);
            let mut o0 = o0f as i32;
            if o0 < 0 {
                o0 += N as i32;
            }
            if o0 >= N as i32 {
                o0 -= N as i32;
            }
            let v_r1 = mag * rf;
            let v_r0 = mag - v_r1;
            let v_rc11 = v_r1 * cf;
            let v_rc10 = v_r1 - v_rc11;
            let v_rc01 = v_r0 * cf;
            let v_rc00 = v_r0 - v_rc01;
            let v_rco111 = v_rc11 * of;
            let v_rco101 = v_rc10 * of;
            let v_rco011 = v_rc01 * of;
            let v_rco001 = v_rc00 * of;
            v[0][k] = v_rc00 - v_rco001;
            v[1][k] = v_rco001;
            v[2][k] = v_rc01 - v_rco011;
            v[3][k] = v_rco011;
            v[4][k] = v_rc10 - v_rco101;
            v[5][k] = v_rco101;
            v[6][k] = v_rc11 - v_rco111;
            v[7][k] = v_rco111;
            // Stale lanes may give a negative index; it is never used (`k >= m`).
            idx[k] = (((r0 + 1) * (D as i32 + 2) + c0 + 1) * (N as i32 + 2) + o0) as usize;
        }
        for k in 0..m {
            let i = idx[k];
            hist[i] += v[0][k];
            hist[i + 1] += v[1][k];
            hist[i + N + 2] += v[2][k];
            hist[i + N + 3] += v[3][k];
            hist[i + rs] += v[4][k];
            hist[i + rs + 1] += v[5][k];
            hist[i + rs + N + 2] += v[6][k];
            hist[i + rs + N + 3] += v[7][k];
        }
        start += m;
    }
}

/// Clamps every element at 0.2·‖v‖₂ and renormalises to unit L2 norm (a zero vector stays
/// zero).
pub fn normalize_descriptor(v: &mut [f32; DESCRIPTOR_LEN]) {
    let nrm = v.iter().map(|x| x * x).sum::<f32>().sqrt();
    let thr = nrm * DESCR_MAG_THR;
    let mut nrm2 = 0f32;
    for x in v.iter_mut() {
        *x = x.min(thr);
        nrm2 += *x * *x;
    }
    let inv = 1.0 / nrm2.sqrt().max(f32::EPSILON);
    for x in v.iter_mut() {
        *x *= inv;
    }
}

/// Quantises a unit-norm descriptor: `saturate_u8(round(512·v))` (OpenCV's output).
pub fn quantize(v: &[f32; DESCRIPTOR_LEN]) -> SiftDescriptor {
    let mut q = [0u8; DESCRIPTOR_LEN];
    for (o, &x) in q.iter_mut().zip(v) {
        *o = (x * INT_DESCR_FCTR).round_ties_even().clamp(0.0, 255.0) as u8;
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalisation_gives_unit_norm_and_clamps() {
        let mut v = [0f32; DESCRIPTOR_LEN];
        v[0] = 10.0;
        v[1] = 1.0;
        v[2] = 1.0;
        normalize_descriptor(&mut v);
        let n: f32 = v.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!((n - 1.0).abs() < 1e-6);
        // The large element was clamped to 0.2 of the norm before renormalising.
        assert!((v[0] / v[1] - 0.2 * (102f32).sqrt()).abs() < 1e-4);
        let q = quantize(&v);
        assert!(q[0] > q[1]);
    }
}
