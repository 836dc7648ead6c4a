//! Keypoint detection: the scan for extrema of the difference-of-Gaussians over 3×3×3 blocks
//! (one pass per row over all DoG layers), OpenCV's sub-pixel refinement with the contrast and
//! edge tests (`adjustLocalExtrema`), and the final keypoint list (sorted, exact duplicates
//! removed, optionally the strongest `max_features`).

use super::SiftParams;
use super::orientation::orient;
use super::scale_space::ScaleSpace;
use super::util::{cv_round, fmax, fmin};
use crate::simd::{isa, multiversion};
use quarry_core::{Keypoint, Plane};

#[cfg(feature = "parallel")]
use rayon::prelude::*;

const IMG_BORDER: usize = 5;
const MAX_INTERP_STEPS: usize = 5;

/// Maximum and minimum of the 3×3 block centred on each pixel of row `r` (1 ≤ r < h − 1) of a
/// `w`-wide plane, for columns 1..w−1 (entries 0 and w−1 are left untouched). Branch-free over
/// whole rows so it vectorises.
#[allow(clippy::inline_always)]
#[inline(always)]
fn block3_row(
    p: &[f32],
    w: usize,
    r: usize,
    vmax: &mut [f32],
    vmin: &mut [f32],
    mx: &mut [f32],
    mn: &mut [f32],
) {
    let a = &p[(r - 1) * w..r * w];
    let b = &p[r * w..(r + 1) * w];
    let c = &p[(r + 1) * w..(r + 2) * w];
    for (((hi, lo), (&x, &y)), &z) in vmax
        .iter_mut()
        .zip(vmin.iter_mut())
        .zip(a.iter().zip(b))
        .zip(c)
    {
        *hi = fmax(fmax(x, y), z);
        *lo = fmin(fmin(x, y), z);
    }
    for (k, (hi, lo)) in mx[1..w - 1]
        .iter_mut()
        .zip(mn[1..w - 1].iter_mut())
        .enumerate()
    {
        *hi = fmax(fmax(vmax[k], vmax[k + 1]), vmax[k + 2]);
        *lo = fmin(fmin(vmin[k], vmin[k + 1]), vmin[k + 2]);
    }
}

/// (layer, column) of the pixels of row `r` that are extrema of their 3×3×3 block in DoG
/// layers 1..=s (non-strict, as OpenCV: ≥ all 26 neighbours when positive, ≤ all when
/// negative) with |D| > `thr`, in (layer, column) order. `buf` holds `(2 + 2·layers)·w`
/// scratch values (never needs zeroing: every entry read is written first).
// Non-lazy `&`/`|` on the comparisons keep the block test branch-free (it vectorises).
#[allow(clippy::inline_always, clippy::needless_bitwise_bool)]
#[inline(always)]
fn scan_row_all_layers_body(
    gauss: &[Plane<f32>],
    r: usize,
    w: usize,
    thr: f32,
    buf: &mut [f32],
) -> Vec<(usize, usize)> {
    let nd = gauss.len() - 1;
    let (vmax, rest) = buf.split_at_mut(w);
    let (vmin, rest) = rest.split_at_mut(w);
    let (d3, rest) = rest.split_at_mut(3 * w);
    let (cur_all, rest) = rest.split_at_mut(nd * w);
    let (mx_all, mn_all) = rest.split_at_mut(nd * w);
    for (l, ((mx, mn), cur)) in mx_all
        .chunks_exact_mut(w)
        .zip(mn_all.chunks_exact_mut(w))
        .zip(cur_all.chunks_exact_mut(w))
        .enumerate()
    {
        // Rows r − 1, r, r + 1 of DoG layer l.
        let (g0, g1) = (&gauss[l].data, &gauss[l + 1].data);
        let span = (r - 1) * w..(r + 2) * w;
        for ((o, &a), &b) in d3.iter_mut().zip(&g1[span.clone()]).zip(&g0[span]) {
            *o = a - b;
        }
        cur.copy_from_slice(&d3[w..2 * w]);
        block3_row(d3, w, 1, vmax, vmin, mx, mn);
    }
    let mut out = Vec::new();
    for layer in 1..nd - 1 {
        let cur = &cur_all[layer * w..(layer + 1) * w];
        let (a, b, c) = (
            &mx_all[(layer - 1) * w..layer * w],
            &mx_all[layer * w..(layer + 1) * w],
            &mx_all[(layer + 1) * w..(layer + 2) * w],
        );
        let (d, e, f) = (
            &mn_all[(layer - 1) * w..layer * w],
            &mn_all[layer * w..(layer + 1) * w],
            &mn_all[(layer + 1) * w..(layer + 2) * w],
        );
        // Branch-free test over blocks of 16 columns (vectorises), then the rare hits.
        const B: usize = 16;
        let end = w - IMG_BORDER;
        let mut col = IMG_BORDER;
        while col < end {
            let m = (end - col).min(B);
            let mut hit = [false; B];
            if m == B {
                // Fixed-size blocks: no bounds check inside the loop, so it vectorises.
                let blk = |x: &[f32]| -> [f32; B] {
                    let mut o = [0f32; B];
                    o.copy_from_slice(&x[col..col + B]);
                    o
                };
                let (v, a, b, c, d, e, f) =
                    (blk(cur), blk(a), blk(b), blk(c), blk(d), blk(e), blk(f));
                let mut any = false;
                for k in 0..B {
                    let hi = fmax(fmax(a[k], b[k]), c[k]);
                    let lo = fmin(fmin(d[k], e[k]), f[k]);
                    let h = ((v[k] > thr) & (v[k] >= hi)) | ((v[k] < -thr) & (v[k] <= lo));
                    hit[k] = h;
                    any |= h;
                }
                if !any {
                    col += m;
                    continue;
                }
            } else {
                for (k, h) in hit.iter_mut().enumerate().take(m) {
                    let i = col + k;
                    let v = cur[i];
                    let hi = fmax(fmax(a[i], b[i]), c[i]);
                    let lo = fmin(fmin(d[i], e[i]), f[i]);
                    *h = ((v > thr) & (v >= hi)) | ((v < -thr) & (v <= lo));
                }
            }
            if hit.iter().any(|&h| h) {
                out.extend(
                    hit.iter()
                        .enumerate()
                        .filter(|&(_, &h)| h)
                        .map(|(k, _)| (layer, col + k)),
                );
            }
            col += m;
        }
    }
    out
}

multiversion!(avx512, avx2: fn scan_row_all_layers => scan_row_all_layers_body(
    gauss: &[Plane<f32>],
    r: usize,
    w: usize,
    thr: f32,
    buf: &mut [f32],
) -> Vec<(usize, usize)>);

/// A refined extremum.
#[derive(Debug, Clone, Copy)]
pub(super) struct Refined {
    pub(super) octave: usize,
    pub(super) layer: usize,
    pub(super) r: usize,
    pub(super) c: usize,
    pub(super) kp: Keypoint,
}

/// Quadratic sub-pixel refinement with the contrast and edge tests (OpenCV's
/// `adjustLocalExtrema`). `octave` is the internal index (0 = first octave).
fn refine(
    ss: &ScaleSpace,
    p: &SiftParams,
    octave: usize,
    layer0: usize,
    r0: usize,
    c0: usize,
) -> Option<Refined> {
    const IMG_SCALE: f32 = 1.0 / 255.0;
    const DERIV: f32 = IMG_SCALE * 0.5;
    const SECOND: f32 = IMG_SCALE;
    const CROSS: f32 = IMG_SCALE * 0.25;
    let s = ss.layers;
    let g = &ss.octaves[octave].gauss;
    let w = g[0].width as usize;
    let h = g[0].height as usize;
    let (mut layer, mut r, mut c) = (layer0 as i64, r0 as i64, c0 as i64);
    let (mut xi, mut xr, mut xc) = (0f32, 0f32, 0f32);
    let mut grad = [0f32; 3];
    let mut converged = false;
    for _ in 0..MAX_INTERP_STEPS {
        let (l, ri, ci) = (layer as usize, r as usize, c as usize);
        let (img, prv, nxt) = (l, l - 1, l + 1);
        // DoG layer `d` at (y, x).
        let at = |d: usize, y: usize, x: usize| g[d + 1].data[y * w + x] - g[d].data[y * w + x];
        grad = [
            (at(img, ri, ci + 1) - at(img, ri, ci - 1)) * DERIV,
            (at(img, ri + 1, ci) - at(img, ri - 1, ci)) * DERIV,
            (at(nxt, ri, ci) - at(prv, ri, ci)) * DERIV,
        ];
        let v2 = at(img, ri, ci) * 2.0;
        let dxx = (at(img, ri, ci + 1) + at(img, ri, ci - 1) - v2) * SECOND;
        let dyy = (at(img, ri + 1, ci) + at(img, ri - 1, ci) - v2) * SECOND;
        let dss = (at(nxt, ri, ci) + at(prv, ri, ci) - v2) * SECOND;
        let dxy = (at(img, ri + 1, ci + 1) - at(img, ri + 1, ci - 1) - at(img, ri - 1, ci + 1)
            + at(img, ri - 1, ci - 1))
            * CROSS;
        let dxs = (at(nxt, ri, ci + 1) - at(nxt, ri, ci - 1) - at(prv, ri, ci + 1)
            + at(prv, ri, ci - 1))
            * CROSS;
        let dys = (at(nxt, ri + 1, ci) - at(nxt, ri - 1, ci) - at(prv, ri + 1, ci)
            + at(prv, ri - 1, ci))
            * CROSS;
        let hm = nalgebra::Matrix3::new(dxx, dxy, dxs, dxy, dyy, dys, dxs, dys, dss);
        let x = hm
            .lu()
            .solve(&nalgebra::Vector3::new(grad[0], grad[1], grad[2]))?;
        xc = -x[0];
        xr = -x[1];
        xi = -x[2];
        if !(xc.is_finite() && xr.is_finite() && xi.is_finite()) {
            return None;
        }
        if xi.abs() < 0.5 && xr.abs() < 0.5 && xc.abs() < 0.5 {
            converged = true;
            break;
        }
        const BIG: f32 = (i32::MAX / 3) as f32;
        if xi.abs() > BIG || xr.abs() > BIG || xc.abs() > BIG {
            return None;
        }
        c += i64::from(cv_round(xc));
        r += i64::from(cv_round(xr));
        layer += i64::from(cv_round(xi));
        if layer < 1
            || layer > s as i64
            || c < IMG_BORDER as i64
            || c >= (w - IMG_BORDER) as i64
            || r < IMG_BORDER as i64
            || r >= (h - IMG_BORDER) as i64
        {
            return None;
        }
    }
    if !converged {
        return None;
    }
    let (l, ri, ci) = (layer as usize, r as usize, c as usize);
    let at = |y: usize, x: usize| g[l + 1].data[y * w + x] - g[l].data[y * w + x];
    let t = grad[0] * xc + grad[1] * xr + grad[2] * xi;
    let contr = at(ri, ci) * IMG_SCALE + t * 0.5;
    if contr.abs() * (s as f32) < p.contrast_threshold as f32 {
        return None;
    }
    let v2 = at(ri, ci) * 2.0;
    let dxx = (at(ri, ci + 1) + at(ri, ci - 1) - v2) * SECOND;
    let dyy = (at(ri + 1, ci) + at(ri - 1, ci) - v2) * SECOND;
    let dxy =
        (at(ri + 1, ci + 1) - at(ri + 1, ci - 1) - at(ri - 1, ci + 1) + at(ri - 1, ci - 1)) * CROSS;
    let tr = dxx + dyy;
    let det = dxx * dyy - dxy * dxy;
    let et = p.edge_threshold as f32;
    if det <= 0.0 || tr * tr * et >= (et + 1.0) * (et + 1.0) * det {
        return None;
    }
    // Position and size as OpenCV computes them in the internal octave, then scaled to input
    // pixels (×0.5 for the up-sampled octave).
    let mult = (1u64 << octave) as f32;
    let mut x = (ci as f32 + xc) * mult;
    let mut y = (ri as f32 + xr) * mult;
    let mut size = (p.sigma as f32) * 2f32.powf((l as f32 + xi) / s as f32) * mult * 2.0;
    if ss.first_octave < 0 {
        let scale = 0.5f32.powi(-ss.first_octave);
        x *= scale;
        y *= scale;
        size *= scale;
    }
    Some(Refined {
        octave,
        layer: l,
        r: ri,
        c: ci,
        kp: Keypoint {
            x,
            y,
            sigma: size * 0.5,
            angle_deg: 0.0,
            response: contr.abs(),
            octave: octave as i32 + ss.first_octave,
            layer: l as i32,
            layer_offset: xi,
        },
    })
}

pub(super) fn find_keypoints(ss: &ScaleSpace, p: &SiftParams) -> Vec<Keypoint> {
    find_keypoints_where(ss, p, &|_, _| true)
}

/// [`find_keypoints`] restricted to the refined extrema whose position (input-image pixels)
/// passes `keep`: only those are given orientations (the orientation histogram is most of the
/// cost of a keypoint), and the result is [`find_keypoints`]' output filtered by `keep`, in the
/// same order (a keypoint's position is its extremum's).
pub(super) fn find_keypoints_where(
    ss: &ScaleSpace,
    p: &SiftParams,
    keep: &(dyn Fn(f32, f32) -> bool + Sync),
) -> Vec<Keypoint> {
    let s = ss.layers;
    // OpenCV's pre-threshold in 0..255 units, floored to an integer (spec 004 §4.3).
    let thr = (0.5 * p.contrast_threshold / s as f64 * 255.0).floor() as f32;
    let mut cands: Vec<(usize, usize, usize, usize)> = Vec::new();
    for (o, oct) in ss.octaves.iter().enumerate() {
        let w = oct.gauss[0].width as usize;
        let h = oct.gauss[0].height as usize;
        if w <= 2 * IMG_BORDER || h <= 2 * IMG_BORDER {
            continue;
        }
        // One pass over the rows: the 3×3 block max/min rows of every DoG layer are computed
        // once per row and shared by the s centre layers that use them.
        let nd = oct.gauss.len() - 1;
        let level = isa();
        let scan_row = |buf: &mut Vec<f32>, r: usize| -> Vec<(usize, usize)> {
            scan_row_all_layers(level, &oct.gauss, r, w, thr, buf)
        };
        let buf_len = (5 + 3 * nd) * w;
        #[cfg(feature = "parallel")]
        let rows: Vec<Vec<(usize, usize)>> = (IMG_BORDER..h - IMG_BORDER)
            .into_par_iter()
            .with_min_len(8)
            .map_init(|| vec![0f32; buf_len], scan_row)
            .collect();
        #[cfg(not(feature = "parallel"))]
        let rows: Vec<Vec<(usize, usize)>> = {
            let mut buf = vec![0f32; buf_len];
            (IMG_BORDER..h - IMG_BORDER)
                .map(|r| scan_row(&mut buf, r))
                .collect()
        };
        // Candidates in (layer, row, column) order, as a layer-by-layer scan gives them.
        for layer in 1..=s {
            for (k, row) in rows.iter().enumerate() {
                let r = IMG_BORDER + k;
                cands.extend(
                    row.iter()
                        .filter(|&&(l, _)| l == layer)
                        .map(|&(l, c)| (o, l, r, c)),
                );
            }
        }
    }
    let run = |&(o, layer, r, c): &(usize, usize, usize, usize)| -> Vec<Keypoint> {
        let mut out = Vec::new();
        if let Some(rf) = refine(ss, p, o, layer, r, c)
            && keep(rf.kp.x, rf.kp.y)
        {
            orient(ss, &rf, &mut out);
        }
        out
    };
    #[cfg(feature = "parallel")]
    let per: Vec<Vec<Keypoint>> = cands.par_iter().with_min_len(32).map(run).collect();
    #[cfg(not(feature = "parallel"))]
    let per: Vec<Vec<Keypoint>> = cands.iter().map(run).collect();
    per.into_iter().flatten().collect()
}

fn kp_cmp(a: &Keypoint, b: &Keypoint) -> std::cmp::Ordering {
    a.x.total_cmp(&b.x)
        .then(a.y.total_cmp(&b.y))
        .then(b.sigma.total_cmp(&a.sigma))
        .then(a.angle_deg.total_cmp(&b.angle_deg))
        .then(b.response.total_cmp(&a.response))
        .then(a.octave.cmp(&b.octave))
        .then(a.layer.cmp(&b.layer))
        .then(a.layer_offset.total_cmp(&b.layer_offset))
}

/// Sorts keypoints and removes those with the same position, size and angle as the previous one.
pub(super) fn sort_dedup(kps: &mut Vec<Keypoint>) {
    kps.sort_by(kp_cmp);
    kps.dedup_by(|b, a| {
        a.x == b.x && a.y == b.y && a.sigma == b.sigma && a.angle_deg == b.angle_deg
    });
}

/// Keeps the `n` strongest keypoints (ties at the cut kept, as OpenCV's `retainBest`), in the
/// sorted order.
pub(super) fn retain_best(kps: &mut Vec<Keypoint>, n: usize) {
    let mut resp: Vec<f32> = kps.iter().map(|k| k.response).collect();
    resp.sort_by(|a, b| b.total_cmp(a));
    let cut = resp[n - 1];
    kps.retain(|k| k.response >= cut);
}
